/* The report's figures (section #figures of templates/submissions/report.html), drawn in the reader's browser with uPlot from
 * the measured series the app serves (each chart's data-src, grader/services/reports/series.py).
 *
 * Why here and not on the server: the series are a few tens of kB read from the database by any API host, where
 * drawing 18 PNGs cost a worker more CPU than the simulation (docs/benchmark.md). Interactive: drag across a chart
 * to zoom into a window (the contact window), double-click or "Whole run" to go back, hover to read every series at a
 * sample in the legend. Runs are told apart by line style and legend text as well as colour. A chart that cannot be
 * drawn says so in its place; the caption under it carries the key numbers in words.
 * Each drawn chart records data-series (series drawn) and data-x-min / data-x-max (its window) for tests and tools.
 */
(function () {
  "use strict";

  var CASE_COLORS = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000"];
  var DASHES = [[], [10, 5], [3, 3], [12, 4, 3, 4], [6, 3], [1, 3], [16, 6]];
  var COUNT_OFFSET = 0.07;
  var ZOOM_BEFORE_S = 0.05, ZOOM_AFTER_S = 0.30;  // the contact window, as the lab's figures zoom it
  var loads = {};
  var plots = {};

  function load(url) {
    if (!loads[url]) {
      loads[url] = fetch(url, {credentials: "same-origin", headers: {Accept: "application/json"}}).then(function (r) {
        if (!r.ok) { throw new Error("the series answered " + r.status); }
        return r.json();
      });
    }
    return loads[url];
  }

  function okRuns(doc, kind) {
    return doc.runs.filter(function (r) { return r.kind === kind && r.series; });
  }

  function line(label, color, dash, extra) {
    var s = {label: label, stroke: color, width: 1.6, dash: dash, spanGaps: true, points: {show: false}};
    return Object.assign(s, extra || {});
  }

  function constant(x, value) {
    return x.map(function () { return value; });
  }

  /* Several runs sampled at their own times share one x axis: uPlot.join aligns them (null where a run has no
   * sample; spanGaps draws through). */
  function joined(tables) {
    return uPlot.join(tables);
  }

  function contactChart(doc, kind) {
    var runs = okRuns(doc, "contact");
    var tables = [], series = [];
    runs.forEach(function (r, i) {
      var s = r.series, y;
      if (kind === "contact-z") { y = s.z; }
      else if (kind === "contact-vz") { y = s.vz; }
      else if (kind === "contact-clearance") { y = s.clearance_mm; }
      else { y = s.contact_count.map(function (c) { return c + COUNT_OFFSET * i; }); }
      tables.push([s.t, y]);
      var label = r.name + " (dt=" + r.dt + " s, substeps=" + r.substeps + ")";
      var extra = kind === "contact-count" ? {paths: uPlot.paths.stepped({align: 1})} : null;
      series.push(line(label, CASE_COLORS[i % CASE_COLORS.length], DASHES[i % DASHES.length], extra));
    });
    var data = joined(tables);
    if (runs.length && kind === "contact-z") {
      data.push(constant(data[0], runs[0].expected_center_z));
      series.push(line("ideal rest height", "#333333", [2, 4], {width: 1}));
    }
    if (runs.length && kind === "contact-clearance") {
      data.push(constant(data[0], 0));
      series.push(line("table top (clearance 0)", "#333333", [], {width: 1}));
      data.push(constant(data[0], runs[0].separation_tolerance * 1e3));
      series.push(line("separation tolerance", "#777777", [2, 4], {width: 1}));
    }
    var units = {"contact-z": "z (m)", "contact-vz": "vz (m/s)", "contact-count": "contacts (offset +" +
                 COUNT_OFFSET + " per case)", "contact-clearance": "clearance (mm)"};
    return {data: data, series: series, y: units[kind], x: "simulated time t (s)", first: firstContact(runs)};
  }

  function firstContact(runs) {
    var times = runs.map(function (r) { return r.metrics.first_contact_time; })
      .filter(function (t) { return t !== null && t !== undefined; });
    return times.length ? Math.min.apply(null, times) : null;
  }

  function frictionChart(doc, kind, name) {
    var run = okRuns(doc, "friction").filter(function (r) { return r.name === name; })[0];
    if (!run) { throw new Error("no measured series for run " + name); }
    var key = {"friction-x": "x", "friction-vx": "vx", "friction-omega": "omega"}[kind];
    var t = run.series.t, data = [t], series = [];
    run.lanes.forEach(function (lane, i) {
      var dash = DASHES[i % DASHES.length];
      data.push(lane[key]);
      series.push(line(lane.name + " (cube \u03bc=" + lane.cube_friction + ")", lane.color, dash, {width: 2}));
      var stop = t.map(function () { return null; });
      if (lane.stop.stopped) { stop[lane.stop.index] = lane[key][lane.stop.index]; }
      data.push(stop);
      series.push({label: lane.name + " stop", stroke: lane.color, fill: lane.color, paths: function () { return null; },
                   points: {show: true, size: 10, stroke: "#000000", fill: lane.color}});
    });
    if (kind === "friction-vx") {
      data.push(constant(t, run.stop_speed), constant(t, -run.stop_speed));
      series.push(line("stop band +" + run.stop_speed + " m/s", "#777777", [2, 4], {width: 1}),
                  line("stop band \u2212" + run.stop_speed + " m/s", "#777777", [2, 4], {width: 1}));
    }
    var units = {"friction-x": "displacement x \u2212 x\u2080 (m)", "friction-vx": "velocity vx (m/s)",
                 "friction-omega": "|angular velocity \u03c9| (rad/s)"};
    return {data: data, series: series, y: units[kind], x: "time since measurement start t (s)", first: null};
  }

  /* A chart the lesson declares (rubric.lesson.SeriesChart): one sampled series of every run of a case kind,
   * overlaid against time; the element says which series, of which runs, on which axis. */
  function seriesChart(doc, el) {
    var key = el.getAttribute("data-series-key"), runs = okRuns(doc, el.getAttribute("data-run-kind"));
    var stepped = el.getAttribute("data-stepped") === "true", marker = el.getAttribute("data-first-contact");
    var tables = [], series = [];
    runs.forEach(function (r, i) {
      if (!r.series[key]) { throw new Error("run " + r.name + " has no series " + key); }
      tables.push([r.series.t, r.series[key]]);
      var extra = stepped ? {paths: uPlot.paths.stepped({align: 1})} : null;
      series.push(line(r.name + " (dt=" + r.dt + " s, substeps=" + r.substeps + ")",
                       CASE_COLORS[i % CASE_COLORS.length], DASHES[i % DASHES.length], extra));
    });
    if (!runs.length) { throw new Error("no measured run of kind " + el.getAttribute("data-run-kind")); }
    var times = marker ? runs.map(function (r) { return r.metrics[marker]; })
      .filter(function (t) { return t !== null && t !== undefined; }) : [];
    return {data: joined(tables), series: series, y: el.getAttribute("data-axis"), x: "simulated time t (s)",
            first: times.length ? Math.min.apply(null, times) : null};
  }

  function build(doc, el) {
    var kind = el.getAttribute("data-chart");
    if (kind.indexOf("series-") === 0) { return seriesChart(doc, el); }
    return kind.indexOf("contact-") === 0 ? contactChart(doc, kind) : frictionChart(doc, kind, el.getAttribute("data-run"));
  }

  function width(el) {
    return Math.max(260, Math.floor(el.clientWidth || el.parentNode.clientWidth || 600));
  }

  function record(u) {
    var el = u.root.parentNode;
    el.setAttribute("data-x-min", String(u.scales.x.min));
    el.setAttribute("data-x-max", String(u.scales.x.max));
  }

  function draw(doc, el) {
    var chart = build(doc, el);
    var narrow = window.matchMedia("(max-width: 40rem)").matches;
    var opts = {
      width: width(el), height: narrow ? 220 : 280,
      scales: {x: {time: false}},
      axes: [{label: chart.x}, {label: chart.y, size: 64}],
      series: [{label: "t (s)", value: function (u, v) { return v === null ? "\u2013" : v.toFixed(3); }}]
        .concat(chart.series),
      cursor: {drag: {x: true, y: false, setScale: true}, sync: {key: el.getAttribute("data-sync") || "report"}},
      legend: {live: true},
      hooks: {setScale: [function (u, key) { if (key === "x") { record(u); } }], ready: [record]},
    };
    el.textContent = "";
    var u = new uPlot(opts, chart.data, el);
    u.firstContact = chart.first;
    plots[el.id] = u;
    el.setAttribute("data-series", String(chart.series.length));
    if (window.ResizeObserver) {
      new ResizeObserver(function () { u.setSize({width: width(el), height: u.height}); }).observe(el);
    }
    return u;
  }

  function fail(el, error) {
    el.textContent = "This chart could not be drawn: " + error.message + ". Its numbers are in the caption below and " +
      "in the data linked there.";
    el.classList.add("chart-failed");
    el.setAttribute("data-series", "0");
  }

  /* "Contact window" zooms the charts that have a first contact to it; "Whole run" resets every chart. */
  function zoom(whole) {
    Object.keys(plots).forEach(function (id) {
      var u = plots[id], t = u.data[0];
      if (whole) {
        u.setScale("x", {min: t[0], max: t[t.length - 1]});
      } else if (u.firstContact !== null) {
        u.setScale("x", {min: u.firstContact - ZOOM_BEFORE_S, max: u.firstContact + ZOOM_AFTER_S});
      }
    });
  }

  function start() {
    var charts = document.querySelectorAll("#figures .chart[data-src]");
    Array.prototype.forEach.call(charts, function (el) {
      load(el.getAttribute("data-src")).then(function (doc) { draw(doc, el); }).catch(function (e) { fail(el, e); });
    });
    Array.prototype.forEach.call(document.querySelectorAll("#figures [data-zoom]"), function (button) {
      button.addEventListener("click", function () { zoom(button.getAttribute("data-zoom") === "whole"); });
    });
  }

  window.reportCharts = {plots: plots};
  if (document.readyState === "loading") { document.addEventListener("DOMContentLoaded", start); } else { start(); }
})();
