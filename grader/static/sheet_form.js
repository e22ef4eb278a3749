// The sheet form saves its draft on the server as the student types (debounced), so closing the browser loses
// nothing. Without this script the form still works: its "Save draft" button posts the same fields.
(function () {
  "use strict";
  var form = document.getElementById("sheet-form");
  var status = document.getElementById("draft-status");
  if (!form || !form.dataset.draftUrl || !window.fetch) { return; }
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
