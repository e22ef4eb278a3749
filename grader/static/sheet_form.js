// The sheet form saves its draft on the server as the student types (debounced), so closing the browser loses
// nothing; after Check or a refused Submit it moves focus to the summary at the top; the configs' held fields open
// with "Change a held field", and a changed one says at once what it voids. Without this script the form still
// works: "Save draft" posts the same fields, "Change a held field" asks the server for the form with them editable,
// and Check says what a change voids.
(function () {
  "use strict";
  var form = document.getElementById("sheet-form");
  var status = document.getElementById("draft-status");

  // Check's summary: focused, so that the page opens where its result is and a screen reader reads it.
  var summary = document.getElementById("check-summary");
  if (summary) { summary.focus(); }

  // A link to a field (the summary's, or any in-page one): open the held fields around it and put focus in it.
  document.addEventListener("click", function (event) {
    var link = event.target.closest ? event.target.closest("a[href^='#']") : null;
    if (!link) { return; }
    var target = document.getElementById(decodeURIComponent(link.getAttribute("href").slice(1)));
    if (!target) { return; }
    var details = target.closest ? target.closest("details") : null;
    if (details && !details.open) { details.open = true; }
    if (target.matches && target.matches("input, select, textarea")) {
      event.preventDefault();
      target.focus();
      target.scrollIntoView({ block: "center" });
    }
  });

  if (!form) { return; }

  // Held fields: "Change a held field" makes them editable in place (a disabled select takes its name back from
  // the hidden input that carried its value).
  function unlock(role) {
    var box = document.getElementById("held-fields-" + role);
    if (!box) { return; }
    box.classList.remove("locked");
    box.querySelectorAll("input[readonly]").forEach(function (input) { input.readOnly = false; });
    box.querySelectorAll("select[data-held-name]").forEach(function (select) {
      var shadow = box.querySelector("input[data-held-shadow='" + select.dataset.heldName + "']");
      select.name = select.dataset.heldName;
      select.disabled = false;
      if (shadow) { shadow.parentNode.removeChild(shadow); }
    });
    var first = box.querySelector("input, select");
    if (first) { first.focus(); }
  }
  form.querySelectorAll("button.unlock-held").forEach(function (button) {
    button.addEventListener("click", function (event) {
      event.preventDefault();
      unlock(button.dataset.role);
      button.parentNode.removeChild(button);
    });
  });

  // A counted held field that differs from its baseline: the role's warning (written by the server, naming the
  // items it voids where they can be told) shows at once, and hides again when every held field is back.
  function same(value, baseline) {
    if (value.trim() === baseline) { return true; }
    var x = Number(value), y = Number(baseline);
    return value.trim() !== "" && baseline !== "" && !isNaN(x) && !isNaN(y) && x === y;
  }
  function heldCheck(role) {
    var warning = document.getElementById("held-warning-" + role);
    if (!warning) { return; }
    var changed = Array.prototype.some.call(form.querySelectorAll("[data-held='" + role + "']"), function (el) {
      return !same(el.value, el.dataset.baseline || "");
    });
    warning.hidden = !changed;
  }
  form.addEventListener("input", function (event) {
    if (event.target.dataset && event.target.dataset.held) { heldCheck(event.target.dataset.held); }
  });
  form.addEventListener("change", function (event) {
    if (event.target.dataset && event.target.dataset.held) { heldCheck(event.target.dataset.held); }
  });

  if (!status || !form.dataset.draftUrl || !window.fetch) { return; }
  var timer = null;
  var DELAY_MS = 800;
  // The page's own language: its messages come in data-msg-* attributes, translated with the page.
  function say(name, fallback, values) {
    var text = form.dataset[name] || fallback;
    Object.keys(values || {}).forEach(function (key) { text = text.split("{" + key + "}").join(values[key]); });
    return text;
  }

  function save() {
    timer = null;
    status.textContent = say("msgSaving", "saving…");
    fetch(form.dataset.draftUrl, { method: "POST", body: new FormData(form), credentials: "same-origin" })
      .then(function (response) {
        return response.text().then(function (text) {
          // the server says when, in the course's time zone as the page's language writes it
          status.textContent = response.ok
            ? say("msgSaved", "draft saved {when}", { when: text.replace(/^saved /, "") })
            : say("msgRefused", "draft not saved ({status}): use Save draft", { status: response.status });
        });
      })
      .catch(function () { status.textContent = say("msgOffline", "draft not saved (offline?): use Save draft"); });
  }

  function later() {
    if (timer !== null) { clearTimeout(timer); }
    timer = setTimeout(save, DELAY_MS);
  }

  form.addEventListener("input", later);
  form.addEventListener("change", later);
})();
