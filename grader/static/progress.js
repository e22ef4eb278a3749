// The progress page (templates/submissions/progress.html): every poll-ms it asks progress.json for the submission's state and
// puts the live part, rendered by the server as the page has it, in place; once graded or failed it goes to the
// report. Without this script the page refreshes itself (its noscript refresh).
(function () {
  "use strict";
  var live = document.getElementById("progress-live");
  if (!live) { return; }
  var url = live.getAttribute("data-poll-url");
  var every = parseInt(live.getAttribute("data-poll-ms"), 10) || 1500;
  var report = live.getAttribute("data-report-url");
  var shown = null;
  var polls = 0;

  function finish() {
    // A moment to read "Graded." before the report replaces the page.
    window.setTimeout(function () { window.location.assign(report); }, 800);
  }

  function apply(data) {
    polls += 1;
    live.setAttribute("data-polls", String(polls));
    if (data.html !== shown) {
      live.innerHTML = data.html;
      shown = data.html;
    }
    live.setAttribute("data-finished", data.finished ? "true" : "false");
    if (data.finished) { finish(); } else { window.setTimeout(poll, every); }
  }

  function poll() {
    fetch(url, { credentials: "same-origin", headers: { "Accept": "application/json" } })
      .then(function (r) {
        if (!r.ok) { throw new Error("progress " + r.status); }
        return r.json();
      })
      .then(apply)
      .catch(function () { window.setTimeout(poll, every * 4); });  // a hiccup: ask again, more slowly
  }

  if (live.getAttribute("data-finished") === "true") { finish(); } else { window.setTimeout(poll, every); }
})();
