"""What the notebook client (client/gradernb) shows, from answers the service gives: the Check's verdicts and errors in
words, the confirmation's facts, the progress bar's words, the report's lines and charts. The service itself is in
tests/integration/test_notebook_client.py; here its answers are written out."""

from __future__ import annotations

import sys

import pytest

from tests.factories import ROOT

sys.path.insert(0, str(ROOT / "client"))  # the client is a distribution of its own, not installed with the service
from gradernb import GraderError, views  # noqa: E402
from gradernb.sheet import Check, Confirmation, Report, Sheet, Submission  # noqa: E402

CHECK = {"passes": False, "errors": [{"field": "sheet.answers.A2.direction", "rule": "Input should be 'decrease'",
                                      "words": "A2 direction"}],
         "configs": [{"role": "extension", "baseline": "N1", "may_change": ["dt", "substeps"], "one_factor": False,
                      "verdict": "...", "violations": ["duration"], "voids": ["X1", "X2"],
                      "changes": [{"field": "dt", "baseline": 0.01, "yours": 0.01, "visual": False},
                                  {"field": "duration", "baseline": 1.5, "yours": 2.0, "visual": False}]}]}


def test_the_check_says_the_violation_and_the_errors_in_words():
    check = Check(CHECK)
    html = check._repr_html_()
    assert "one-factor violation" in html and "may not change" in html and "X1, X2" in html
    assert "A2 direction" in html and "Check: what to look at before submitting" in html
    assert repr(check).splitlines() == ["Check: what to look at before submitting",
                                        "  A2 direction: Input should be 'decrease'",
                                        "  extension vs N1: one-factor violation: duration may not change"]
    assert Check({"passes": True, "errors": [], "configs": []})._repr_html_().count("nothing to fix") == 1


def test_the_confirmation_says_attempt_lateness_and_penalty():
    assert repr(Confirmation("Week 3", {"attempt": 2, "max_attempts": 3, "late": "1 h late (1 day charged)",
                                        "penalty": 0.1})) == \
        "Week 3: submitting attempt 2 of 3, 1 h late (1 day charged), late penalty 10%"
    assert "not taken now: closed" in repr(Confirmation("Week 3", {"refused": "closed"}))


def test_the_progress_bar_says_the_queue_place_and_the_time_left():
    html, words = views.progress_html({"status": "running", "own_s": 12.4, "ahead_s": 3, "runs": [
        {"status": "done"}, {"status": "queued", "position": 4, "backend": "cpu"},
        {"status": "queued", "position": 2, "backend": "cpu"}]})
    assert words == "1 of 3 case runs done; submission running; next in queue: place 2 (cpu); about 15 s left"
    assert '<progress max="3" value="1"' in html


def test_the_report_shows_the_total_the_lab_check_the_items_and_the_charts():
    grade = {"total": 29.0, "max_total": 30.0, "check": {"passed": True, "verdict_line": "L03 CHECK: PASSED"},
             "items": [{"id": "A2", "verdict": "credit", "score": 1.0, "max_score": 1.0, "feedback": "ok",
                        "evidence": {"N1": 0.013}}], "pending": None}
    series = {"runs": [{"name": "N1", "series": {"t": [0.0, 0.5, 1.0], "z": [0.8, 0.7, 0.725]}},
                       {"name": "table", "series": {"t": [0, 1]}, "lanes": [{"name": "low", "x": [0, 0.4]}]}],
              "withheld": {}}
    report = Report(Submission(None, {"id": 7}), grade, series)
    report.submission.grader = type("G", (), {"url": "http://grader"})()
    html = report._repr_html_()
    assert "29 / 30" in html and "L03 CHECK: PASSED" in html and "credit" in html and "N1: 0.013" in html
    assert html.count("<svg") == 2 and "http://grader/submissions/7" in html


def test_setting_a_field_the_item_lacks_is_named():
    sheet = Sheet(None, {"assignment_id": 1, "title": "Week 3", "lesson": "L03", "part": "sheet", "configs": [],
                         "draft": {"lesson": "L03", "student": "alice", "answers": {}},
                         "items": [{"id": "A2", "question": "?", "fields": [
                             {"path": "answers.A2.direction"}, {"path": "answers.A2.explanation"}]}]})
    sheet.set("A2", direction="decrease")
    assert sheet.as_dict() == {"lesson": "L03", "student": "alice", "answers": {"A2": {"direction": "decrease"}}}
    with pytest.raises(GraderError, match="A2: no field dirction"):
        sheet.set("A2", dirction="decrease")
    with pytest.raises(GraderError, match="B9: not a question of Week 3"):
        sheet.set("B9", lane="low")
    sheet.collect({"A2": {"direction": "increase"}, "B9": {"x": 1}})
    assert sheet.answers == {"A2": {"direction": "increase"}}


def test_a_withheld_report_says_why_instead_of_failing():
    class Refusing:
        url = "http://grader"

        def call(self, method, path, **_):
            raise GraderError(409, "grade of submission 7 is withheld: every item is shown from the due date")

    shown = Submission(Refusing(), {"id": 7}).report()
    assert repr(shown) == "submission 7: grade of submission 7 is withheld: every item is shown from the due date"
    assert "http://grader/submissions/7" in shown._repr_html_()


def test_a_refused_submission_names_each_field_in_the_students_words():
    sheet = Sheet(None, {"assignment_id": 1, "title": "Week 3", "lesson": "L03", "part": "sheet", "configs": [],
                         "draft": {"lesson": "L03", "student": "alice", "answers": {}},
                         "items": [{"id": "A2", "question": "?", "fields": [
                             {"path": "answers.A2.direction", "words": "A2 direction"}]}]})
    refused = sheet._worded(GraderError(422, "invalid sheet", [
        {"field": "sheet.answers.A2.direction", "rule": "Input should be 'decrease'"},
        {"field": "assignment_id", "rule": "closed"}]))
    assert str(refused).splitlines() == ["invalid sheet (HTTP 422)", "  A2 direction: Input should be 'decrease'",
                                         "  assignment_id: closed"]
