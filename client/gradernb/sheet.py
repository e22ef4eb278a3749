"""A sheet being answered in the notebook (the page's draft), its Check, its submission and the report."""

from __future__ import annotations

import copy
import time
from html import escape
from typing import Any

from gradernb import views
from gradernb.api import Grader, GraderError

FINISHED = ("graded", "failed")


class Check:
    """The sheet page's Check as the service answered it: errors with their field in your words, and each config's
    one-factor verdict (the items a broken config would void)."""

    def __init__(self, data: dict):
        self.data = data
        self.passes, self.errors, self.configs = data["passes"], data["errors"], data["configs"]

    @property
    def violations(self) -> list[dict]:
        return [c for c in self.configs if not c["one_factor"]]

    def _heading(self) -> str:
        return "Check: nothing to fix" if self.passes else "Check: what to look at before submitting"

    def _repr_html_(self) -> str:
        out = [views.STYLE, f"<h4>{escape(self._heading())}</h4>"]
        if self.passes:
            out.append("<p>The sheet passes every rule a submission checks.</p>")
        if self.errors:
            out.append(f"<p>{len(self.errors)} problem(s) stop this sheet from being taken:</p>")
            out.append(views.html_table(["where", "rule"], [[e["words"], e["rule"]] for e in self.errors]))
        for c in self.configs:
            verdict = (views.Html('<span class="ok">one factor</span>') if c["one_factor"]
                       else views.Html('<span class="bad">one-factor violation</span>'))
            out.append(f"<h5>{escape(c['role'])} vs {escape(c['baseline'])}: {verdict}</h5>")
            rows = [[ch["field"], ch["baseline"], ch["yours"],
                     "may not change" if ch["field"] in c["violations"] else
                     ("visual only, not counted" if ch["visual"] else "may change")] for ch in c["changes"]]
            if rows:
                out.append(views.html_table(["field", "baseline", "yours", "rule"], rows))
            if not c["one_factor"]:
                voids = ", ".join(c["voids"]) or "every item that compares its run"
                out.append(f"<p>Submitted like this, the grader voids {escape(voids)} (no credit), and the config "
                           "is never run.</p>")
        return "".join(out)

    def __repr__(self) -> str:
        lines = [self._heading()]
        lines += [f"  {e['words']}: {e['rule']}" for e in self.errors]
        for c in self.configs:
            lines.append(f"  {c['role']} vs {c['baseline']}: "
                         + ("one factor" if c["one_factor"] else "one-factor violation: "
                            + ", ".join(c["violations"]) + " may not change"))
        return "\n".join(lines)


class Sheet:
    """Your sheet for one assignment: starts from the draft the sheet page keeps; `set`, `config` or `collect` change
    it here, `save` stores it as that same draft, `check` and `submit` go through the service's rules."""

    def __init__(self, grader: Grader, data: dict):
        self.grader, self.data = grader, data
        self.assignment_id, self.title = data["assignment_id"], data["title"]
        draft = copy.deepcopy(data["draft"])
        self.lesson, self.student = draft.get("lesson") or data["lesson"], draft.get("student")
        self.answers: dict[str, Any] = draft.get("answers") or {}
        self.configs: dict[str, Any] = draft.get("configs") or {}
        self.items = {item["id"]: item for item in data["items"]}

    # --- answering ----------------------------------------------------------------------------------------------------
    def fields(self, item_id: str) -> list[str]:
        """The answer fields of an item (top level: `direction`, `explanation`; `baseline` holds `low` and `high`)."""
        prefix = f"answers.{item_id}."
        return list(dict.fromkeys(f["path"].removeprefix(prefix).split(".")[0] for f in self._item(item_id)["fields"]))

    def _item(self, item_id: str) -> dict:
        if item_id not in self.items:
            raise GraderError(0, f"{item_id}: not a question of {self.title} (its questions: "
                                 f"{', '.join(self.items)})")
        return self.items[item_id]

    def set(self, item_id: str, answer: dict | None = None, **fields) -> Sheet:
        """Answer an item, whole (`set("A2", {"direction": "decrease"})`) or field by field (`set("A2",
        direction="decrease")`); a field the item does not have is named here."""
        values = dict(answer or {}) | fields
        known = self.fields(item_id)
        unknown = [name for name in values if name not in known]
        if unknown:
            raise GraderError(0, f"{item_id}: no field {', '.join(unknown)} (its fields: {', '.join(known)})")
        self.answers[item_id] = (self.answers.get(item_id) or {}) | values if answer is None else values
        return self

    def config(self, role: str, config: dict | None = None, **fields) -> Sheet:
        """Set a config (`config("extension", dt=0.01, substeps=4)`); fields left out keep the lesson's values."""
        roles = [c["role"] for c in self.data["configs"]]
        if role not in roles:
            raise GraderError(0, f"{role}: not a config of {self.title} (its configs: {', '.join(roles) or 'none'})")
        self.configs[role] = (self.configs.get(role) or {}) | fields if config is None else dict(config) | fields
        return self

    def collect(self, namespace: dict) -> Sheet:
        """Take every answer and config a notebook's cells assigned (`A2 = {...}`, `extension = {...}`): pass
        `globals()`."""
        for item_id in self.items:
            if isinstance(namespace.get(item_id), dict):
                self.set(item_id, namespace[item_id])
        for c in self.data["configs"]:
            if isinstance(namespace.get(c["role"]), dict):
                self.config(c["role"], namespace[c["role"]])
        return self

    def as_dict(self) -> dict:
        """The sheet the service takes."""
        sheet = {"lesson": self.lesson, "student": self.student or "", "answers": self.answers}
        if self.configs:
            sheet["configs"] = self.configs
        return sheet

    def words(self, field: str) -> str:
        """A field the service names (`sheet.answers.A2.direction`) in the student's words ("A2 direction")."""
        path = field.removeprefix("sheet.")
        for item in self.items.values():
            for f in item["fields"]:
                if path == f["path"] or path.startswith(f["path"] + "."):
                    return f.get("words") or f["path"]
        return path

    def _worded(self, refused: GraderError) -> GraderError:
        for error in refused.errors:
            error.setdefault("words", self.words(error.get("field", "")))
        return GraderError(refused.status, refused.detail, refused.errors)

    # --- the service's rules ------------------------------------------------------------------------------------------
    def save(self) -> str:
        """Store this sheet as your draft: the one the sheet page shows. Returns when it was saved."""
        return self.grader.call("PUT", f"/assignments/{self.assignment_id}/sheet/draft",
                                json={"sheet": self.as_dict()})["saved_at"]

    def check(self) -> Check:
        """The sheet page's Check (nothing saved): shown as a table in Jupyter."""
        return Check(self.grader.call("POST", f"/assignments/{self.assignment_id}/sheet/check",
                                      params={"language": self.grader.language}, json={"sheet": self.as_dict()}))

    def standing(self) -> dict:
        """What a submission now would be: attempt, lateness and penalty, or the rule that refuses it."""
        return self.grader.call("GET", f"/assignments/{self.assignment_id}/sheet",
                                params={"language": self.grader.language})["standing"]

    def submit(self, *, accept_voids: bool = False, follow: bool = True, poll_s: float = 1.0,
               timeout_s: float | None = None) -> Submission:
        """Save the draft, show the confirmation's facts (attempt, lateness, penalty), submit, then follow the runs
        with a progress bar until the report is complete. A config the one-factor rule voids is submitted only with
        `accept_voids=True` (the page's second tick)."""
        standing = self.standing()
        views.show(Confirmation(self.title, standing))
        if standing.get("refused"):
            raise GraderError(409, f"not taken now: {standing['refused']}")
        check = self.check()
        if check.violations and not accept_voids:
            views.show(check)
            raise GraderError(0, "a config breaks the one-factor rule: fix it, or submit(accept_voids=True) knowing "
                                 "the items it voids get no credit")
        try:
            self.save()
            created = self.grader.call("POST", "/submissions",
                                       json={"sheet": self.as_dict(), "assignment_id": self.assignment_id})
        except GraderError as refused:  # each field in the student's words, as the check says them
            raise self._worded(refused) from None
        submission = Submission(self.grader, created)
        if follow:
            submission.follow(poll_s=poll_s, timeout_s=timeout_s)
        return submission

    def _repr_html_(self) -> str:
        rows = [[item_id, item["question"], self.answers.get(item_id)] for item_id, item in self.items.items()]
        lab = f"<p>Your lab: {escape(self.data['lab'])}</p>" if self.data.get("lab") else ""
        return (views.STYLE + f"<h4>{escape(self.title)}: your sheet ({escape(self.data['part'])})</h4>" + lab
                + views.html_table(["item", "question", "your answer"], rows))


class Confirmation:
    def __init__(self, title: str, standing: dict):
        self.title, self.standing = title, standing

    def words(self) -> str:
        s = self.standing
        if s.get("refused"):
            return f"{self.title}: not taken now: {s['refused']}"
        of = f" of {s['max_attempts']}" if s.get("max_attempts") else ""
        penalty = f"late penalty {round(100 * s['penalty'])}%" if s.get("penalty") else "no late penalty"
        return f"{self.title}: submitting attempt {s['attempt']}{of}, {s['late']}, {penalty}"

    def _repr_html_(self) -> str:
        return f'<p class="gradernb"><strong>{escape(self.words())}</strong></p>'

    def __repr__(self) -> str:
        return self.words()


class Submission:
    """A submission: `follow` shows its progress, `report` its report (once graded)."""

    def __init__(self, grader: Grader, data: dict):
        self.grader, self.data, self.id = grader, data, data["id"]

    @property
    def url(self) -> str:
        return f"{self.grader.url}/submissions/{self.id}"

    def refresh(self) -> dict:
        self.data = self.grader.call("GET", f"/submissions/{self.id}")
        return self.data

    def follow(self, *, poll_s: float = 1.0, timeout_s: float | None = None) -> dict:
        """A progress bar while the cases run (runs done, the next run's place in its queue, the time left), until
        the submission failed or its report is complete."""
        live = views.Live()
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            progress = self.grader.call("GET", f"/submissions/{self.id}/progress")
            html, words = views.progress_html(progress)
            live.update(html, words)
            state = self.refresh()
            if state["status"] == "failed" or (state["status"] == "graded" and state.get("report_complete")):
                html, words = views.progress_html(self.grader.call("GET", f"/submissions/{self.id}/progress"))
                live.update(html, words)
                return state
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"submission {self.id} still {state['status']} after {timeout_s} s")
            time.sleep(poll_s)

    def report(self) -> Report:
        """The report: total, the lab check line, each item's verdict and evidence, the charts, a link to the page."""
        try:
            grade = self.grader.call("GET", f"/submissions/{self.id}/grade")
        except GraderError as refused:  # 409: not graded yet, or every score withheld until the due date or release
            if refused.status != 409:
                raise
            return Withheld(self, refused.detail)
        series = self.grader.call("GET", f"/submissions/{self.id}/series")
        return Report(self, grade, series)


class Report:
    def __init__(self, submission: Submission, grade: dict, series: dict):
        self.submission, self.grade, self.series = submission, grade, series
        self.total, self.max_total = grade["total"], grade["max_total"]
        self.check_line = (grade.get("check") or {}).get("verdict_line")
        self.items = {item["id"]: item for item in grade["items"]}

    def _repr_html_(self) -> str:
        g = self.grade
        out = [views.STYLE, f"<h3>Submission {self.submission.id}: {g['total']:g} / {g['max_total']:g}</h3>"]
        if self.check_line:
            cls = "ok" if (g.get("check") or {}).get("passed") else "bad"
            out.append(f'<p class="gradernb"><span class="{cls}">{escape(self.check_line)}</span></p>')
        if g.get("pending"):
            out.append(f"<p>{escape(g['pending'])}</p>")
        rows = [[i["id"], i["verdict"], "–" if i["score"] is None else f"{i['score']:g} / {i['max_score']:g}",
                 i.get("feedback") or "", _evidence(i.get("evidence"))] for i in g["items"]]
        out.append(views.html_table(["item", "verdict", "score", "feedback", "measured evidence"], rows))
        out.append(views.charts_html(self.series))
        out.append(f'<p><a href="{escape(self.submission.url)}" target="_blank">The report page</a> '
                   "(sign in there to ask for a review)</p>")
        return "".join(out)

    def __repr__(self) -> str:
        lines = [f"submission {self.submission.id}: {self.total:g} / {self.max_total:g}"]
        if self.check_line:
            lines.append(self.check_line)
        lines += [f"  {i['id']}: {i['verdict']} {i['score']}" for i in self.grade["items"]]
        lines.append(self.submission.url)
        return "\n".join(lines)


class Withheld:
    """A report not shown yet: why (not graded yet, or its assignment withholds every score until a date or a
    release), as the report page says it."""

    def __init__(self, submission: Submission, why: str):
        self.submission, self.why = submission, why

    def _repr_html_(self) -> str:
        return (f'<p class="gradernb">Submission {self.submission.id}: {escape(self.why)}. '
                f'<a href="{escape(self.submission.url)}" target="_blank">The report page</a></p>')

    def __repr__(self) -> str:
        return f"submission {self.submission.id}: {self.why}"


def _evidence(evidence: Any) -> str:
    if evidence is None:
        return ""
    if isinstance(evidence, dict):
        return "; ".join(f"{k}: {views.text(v)}" for k, v in list(evidence.items())[:6])
    return views.text(evidence)[:300]
