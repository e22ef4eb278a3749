// The sheet form saves its draft on the server as the student types (debounced), so closing the browser loses
// nothing. Without this script the form still works: its "Save draft" button posts the same fields.
(function () {
  "use strict";
  var form = document.getElementById("sheet-form");
  var status = document.getElementById("draft-status");
  if (!form || !form.dataset.draftUrl || !window.fetch) { return; }
  var timer = null;
  var DELAY_MS = 800;

  function save() {
    timer = null;
    status.textContent = "saving…";
    fetch(form.dataset.draftUrl, { method: "POST", body: new FormData(form), credentials: "same-origin" })
      .then(function (response) {
        return response.text().then(function (text) {
          status.textContent = response.ok ? "draft " + text : "draft not saved (" + response.status + "): use Save draft";
        });
      })
      .catch(function () { status.textContent = "draft not saved (offline?): use Save draft"; });
  }

  function later() {
    if (timer !== null) { clearTimeout(timer); }
    timer = setTimeout(save, DELAY_MS);
  }

  form.addEventListener("input", later);
  form.addEventListener("change", later);
})();
