"""Assignments on the in-process app (SQLite): creation and its refusals, the CLI, submitting to one."""

from __future__ import annotations

from datetime import UTC, timedelta

import pytest
from sqlalchemy import func, select

def at(days: float = 0, hours: float = 0) -> str:
    """An instant relative to the service's now (grader.core.clock, frozen or shifted), ISO 8601 with its offset."""
    from grader.core import clock

    return (clock.now().replace(microsecond=0, tzinfo=UTC) + timedelta(days=days, hours=hours)).isoformat()


def body(**over) -> dict:
    return {"title": "Checkpoints", "part": "checkpoints", "open_at": at(-1), "due_at": at(1), "hard_close_at": at(3),
            **over}


def create(api, who="prof", course="l03", **over):
    return api.client.post(f"/v1/courses/{course}/assignments", json=body(**over), headers=api.as_(who))


def assignment_count() -> int:
    from grader.core.db import new_session
    from grader.core.models import Assignment

    with new_session() as session:
        return session.scalar(select(func.count()).select_from(Assignment))


@pytest.mark.clock("2026-11-20T12:00:00Z")
def test_an_instructor_creates_an_assignment_everyone_in_the_course_lists_it(api):
    response = create(api, open_at="2026-12-01T10:00:00+01:00", due_at="2026-12-08T09:00:00Z",
                      hard_close_at="2026-12-10T09:00:00Z", late_penalty_per_day=0.1, late_penalty_cap=0.3,
                      max_attempts=2, counted_attempt="best", visibility="after_due")
    assert response.status_code == 201, response.text
    row = response.json()
    assert row["open_at"] in ("2026-12-01T09:00:00Z", "2026-12-01T09:00:00+00:00")  # stored UTC, returned with offset
    assert row["item_ids"] == ["C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8"]
    assert (row["max_attempts"], row["counted_attempt"], row["visibility"], row["created_by"]) == (
        2, "best", "after_due", "prof")
    for who in ("alice", "tess", "prof"):
        listed = api.client.get("/v1/courses/l03/assignments", headers=api.as_(who))
        assert listed.status_code == 200 and [a["id"] for a in listed.json()] == [row["id"]]
        assert api.client.get(f"/v1/assignments/{row['id']}", headers=api.as_(who)).json() == row


@pytest.mark.parametrize("part, part_ids", [("exercises", 18), ("sheet", 26)])
def test_exercises_are_every_item_but_the_checkpoints(api, part, part_ids):
    row = create(api, part=part).json()
    assert len(row["item_ids"]) == part_ids and ("C1" in row["item_ids"]) == (part == "sheet")


@pytest.mark.parametrize("over, field, rule", [
    ({"due_at": "2026-12-08T09:00:00"}, "due_at", "timezone"),  # not a clock time: refused for its missing offset
    ({"due_at": at(-2)}, "due_at", "due_at must be after open_at"),
    ({"hard_close_at": at(0)}, "hard_close_at", "hard_close_at must not be before due_at"),
    ({"late_penalty_per_day": 1.5}, "late_penalty_per_day", "less than or equal to 1"),
    ({"late_penalty_cap": -0.1}, "late_penalty_cap", "greater than or equal to 0"),
    ({"max_attempts": 0}, "max_attempts", "greater than or equal to 1"),
    ({"part": "everything"}, "part", "checkpoints"),
    ({"counted_attempt": "first"}, "counted_attempt", "latest"),
    ({"visibility": "never"}, "visibility", "on_release"),
    ({"open_at": "0001-01-01T00:00:00+05:00"}, "open_at", "outside the representable range"),
    ({"title": ""}, "title", "at least 1"),
    ({"deadline": at(1)}, "deadline", "Extra inputs"),
])
def test_bad_assignments_are_refused_naming_field_and_rule_nothing_stored(api, over, field, rule):
    response = create(api, **over)
    assert response.status_code == 422, response.text
    assert any(e["field"] == field and rule in e["rule"] for e in response.json()["errors"]), response.json()
    assert assignment_count() == 0


def test_only_an_instructor_of_the_course_creates(api):
    assert create(api, who="alice").status_code == 403
    assert create(api, who="tess").status_code == 403
    assert create(api, who="eve").status_code == 404  # another course's instructor learns nothing
    assert create(api, who="eve", course="other").status_code == 201
    assert assignment_count() == 1
    other = api.client.get("/v1/courses/other/assignments", headers=api.as_("eve")).json()[0]
    assert api.client.get(f"/v1/assignments/{other['id']}", headers=api.as_("alice")).status_code == 404
    assert api.client.get("/v1/assignments/2147483648", headers=api.as_("alice")).status_code == 422


def test_the_cli_creates_and_lists_over_http(api, monkeypatch):
    from click.testing import CliRunner
    from fastapi.testclient import TestClient

    from grader.cli import assignment, main
    from grader.client import Client
    from grader.main import app

    def client(url, token):
        c = Client(url, token)
        c.http = TestClient(app, base_url="http://testserver/v1", headers={"Authorization": f"Bearer {token}"})
        return c

    monkeypatch.setattr(assignment, "_client", client)
    made = CliRunner().invoke(main, ["assignment", "create", "l03", "--title", "Lab 3", "--part", "sheet",
                                     "--open", at(-1), "--due", at(1), "--close", at(2), "--penalty-per-day", "0.1",
                                     "--max-attempts", "3", "--token", api.tokens["prof"]])
    assert made.exit_code == 0, made.output
    assert "assignment #1 'Lab 3' (sheet: A1," in made.output
    listed = CliRunner().invoke(main, ["assignment", "list", "l03", "--token", api.tokens["alice"]])
    assert listed.exit_code == 0 and "Lab 3" in listed.output and "attempts 3" in listed.output
    refused = CliRunner().invoke(main, ["assignment", "create", "l03", "--title", "x", "--open", at(1), "--due", at(0),
                                        "--close", at(2), "--token", api.tokens["prof"]])
    assert refused.exit_code != 0 and "due_at: due_at must be after open_at" in refused.output


def checkpoint_sheet(student: str = "alice") -> dict:
    from rubric.sheet import CHECKPOINT_IDS
    from tests.factories import reference_sheet

    sheet = reference_sheet()
    return {"lesson": "L03", "student": student,
            "answers": {k: v for k, v in sheet["answers"].items() if k in CHECKPOINT_IDS}}


def submit(api, assignment_id, who="alice", sheet=None):
    return api.client.post("/v1/submissions", json={"sheet": sheet or checkpoint_sheet(who),
                                                    "assignment_id": assignment_id}, headers=api.as_(who))


@pytest.fixture(autouse=True)
def lesson_cases_stored(request):
    """Checkpoint sheets here are graded on the lesson's cases as really measured and stored (tests marked
    `lesson_unmeasured` see a service where none was measured yet)."""
    if request.node.get_closest_marker("lesson_unmeasured") is None:
        request.getfixturevalue("lesson_measured")


def stored() -> tuple[int, int]:
    """Submissions and case runs stored in course l03 (the lesson's measured cases belong to another course's)."""
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Course, Submission

    with new_session() as session:
        course = select(Course.id).where(Course.name == "l03").scalar_subquery()
        return (session.scalar(select(func.count()).select_from(Submission).where(Submission.course_id == course)),
                session.scalar(select(func.count()).select_from(CaseRun).join(Submission)
                               .where(Submission.course_id == course)))


def refused(response, *words: str) -> None:
    assert response.status_code == 409, response.text
    (err,) = response.json()["errors"]
    assert err["field"] == "assignment_id" and all(w in err["rule"] for w in words), err


def test_a_checkpoint_submission_runs_no_case_and_is_graded_at_once_on_its_items_only(api, lesson_measured):
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    aid = create(api).json()["id"]
    response = submit(api, aid)
    assert response.status_code == 202, response.text
    row = response.json()
    # At once: the answer to the POST itself is the graded submission (no worker was asked to do anything).
    assert (row["status"], row["attempt"], row["late_seconds"]) == ("graded", 1, 0)
    # Nothing run or queued: each lesson case is recorded as reusing its stored measurement.
    assert row["progress"]["total"] == row["progress"]["done"] == len(lesson_measured)
    assert api.sent == [] and stored() == (1, len(lesson_measured))
    with new_session() as session:  # no run was ever claimed, started or tried by a worker
        runs = session.scalars(select(CaseRun).where(CaseRun.submission_id == row["id"])).all()
        assert {(r.status, r.tries, r.started_at, r.worker, r.lease_until) for r in runs} == {
            ("done", 0, None, None, None)}
    runs = api.client.get(f"/v1/submissions/{row['id']}/case-runs", headers=api.as_("alice")).json()
    assert {r["name"]: r["reused_from_id"] for r in runs} == lesson_measured
    grade = api.client.get(f"/v1/submissions/{row['id']}/grade", headers=api.as_("alice")).json()
    assert [i["id"] for i in grade["items"]] == ["C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8"]
    assert grade["max_total"] == 8  # the other 22 points of the sheet are not this assignment's
    # Graded on the lesson's cases as stored: the measured checkpoints read them, and the reference answers score all.
    assert {i["id"]: i["verdict"] for i in grade["items"]} == dict.fromkeys(grade_ids(grade), "credit")
    items = {i["id"]: i for i in grade["items"]}
    assert items["C1"]["backends"] == {"N4": "cpu"} and items["C5"]["backends"] == {"friction-baseline": "cpu"}
    events = api.client.get(f"/v1/submissions/{row['id']}/events", headers=api.as_("prof")).json()
    assert "no case run" in next(e["detail"] for e in events if e["state"] == "graded")


def grade_ids(grade) -> list[str]:
    return [i["id"] for i in grade["items"]]


@pytest.mark.lesson_unmeasured
def test_a_checkpoint_submission_on_a_service_that_never_measured_the_lesson_queues_its_cases(api):
    """Nothing counted against the student for a measurement the service lacks: the lesson's cases are queued for
    this submission (the worker runs them once, every later checkpoint sheet reuses them) and it is graded after."""
    from rubric.scoring import LESSON_RUNS

    aid = create(api).json()["id"]
    row = submit(api, aid).json()
    assert row["status"] != "graded" and row["total"] is None
    assert row["progress"]["total"] == len(api.sent) == len(LESSON_RUNS) and stored() == (1, len(LESSON_RUNS))
    assert api.client.get(f"/v1/submissions/{row['id']}/grade", headers=api.as_("prof")).status_code == 409  # not yet


def test_a_checkpoint_submission_with_one_lesson_case_never_measured_queues_it(api, lesson_measured):
    from sqlalchemy import delete

    from grader.core.db import new_session
    from grader.core.models import Measurement

    with new_session() as session:  # friction-baseline was never measured under this key (say, another engine)
        session.execute(delete(Measurement).where(Measurement.case_run_id == lesson_measured["friction-baseline"]))
        session.commit()
    row = submit(api, create(api).json()["id"]).json()
    assert row["status"] != "graded" and row["progress"]["total"] == len(lesson_measured)
    assert row["progress"]["done"] == len(lesson_measured) - 1 and len(api.sent) == 1  # only it is measured


def test_answers_outside_the_assignment_are_refused_naming_them(api):
    from tests.factories import reference_sheet

    aid = create(api).json()["id"]
    response = submit(api, aid, sheet=reference_sheet())
    assert response.status_code == 422
    fields = {e["field"] for e in response.json()["errors"]}
    assert "sheet.answers.A1" in fields and any(f.startswith("sheet.configs.") for f in fields), fields
    assert stored() == (0, 0)


def test_an_exercise_submission_queues_its_cases_and_holds_no_checkpoint(api):
    from rubric.sheet import CHECKPOINT_IDS
    from tests.factories import reference_sheet

    aid = create(api, part="exercises").json()["id"]
    sheet = reference_sheet()
    sheet["answers"] = {k: v for k, v in sheet["answers"].items() if k not in CHECKPOINT_IDS}
    response = submit(api, aid, sheet=sheet)
    assert response.status_code == 202, response.text
    progress = response.json()["progress"]
    # Its own two configs are queued; the lesson's 7 cases reuse their stored measurements.
    assert response.json()["status"] == "running" and (progress["total"], progress["done"]) == (9, 7)
    assert len(api.sent) == progress["queued"] == 2


def test_before_open_after_close_and_beyond_attempts_are_refused_with_the_rule_and_time(api):
    early = create(api, open_at=at(1), due_at=at(2), hard_close_at=at(3)).json()
    refused(submit(api, early["id"]), "opens at", early["open_at"][:19])
    closed = create(api, open_at=at(-3), due_at=at(-2), hard_close_at=at(-1)).json()
    refused(submit(api, closed["id"]), "closed at", closed["hard_close_at"][:19], "hard close")
    assert stored() == (0, 0)
    limited = create(api, max_attempts=2).json()
    assert [submit(api, limited["id"]).json()["attempt"] for _ in range(2)] == [1, 2]
    refused(submit(api, limited["id"]), "allows 2 attempts", "2 already submitted")
    assert stored() == (2, 2 * 7)  # each graded on the 7 lesson cases, reused
    assert submit(api, limited["id"], who="bob").json()["attempt"] == 1  # attempts are counted per student


def test_an_unknown_or_foreign_assignment_is_refused(api):
    other = create(api, who="eve", course="other").json()["id"]
    for aid in (other, 999):
        response = submit(api, aid)
        assert response.status_code == 422 and response.json()["errors"][0]["field"] == "assignment_id"
    assert stored() == (0, 0)


def test_a_late_submission_records_how_late(api):
    aid = create(api, due_at=at(hours=-2), hard_close_at=at(1)).json()["id"]
    late = submit(api, aid).json()["late_seconds"]
    assert 2 * 3600 <= late < 2 * 3600 + 60


def test_a_shifted_clock_dates_the_service_that_many_days_ahead(api, monkeypatch):
    """settings.clock_shift_days (CLOCK_SHIFT_DAYS, a rehearsal of a term) moves the service's "now": an assignment
    due a day from now by the calendar is already a day past due to a service living two days ahead, and the
    submission is stored as made two days from now."""
    from datetime import datetime

    from grader.core import clock
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "clock_shift_days", 2.0)
    calendar = datetime.now(UTC).replace(microsecond=0)  # the system clock, which the shift never moves
    aid = create(api, open_at=(calendar - timedelta(days=1)).isoformat(),
                 due_at=(calendar + timedelta(days=1)).isoformat(),
                 hard_close_at=(calendar + timedelta(days=3)).isoformat()).json()["id"]
    made = submit(api, aid)
    assert made.status_code == 202, made.text
    row = made.json()
    assert 86400 <= row["late_seconds"] < 86400 + 60, row["late_seconds"]
    created = datetime.fromisoformat(row["created_at"].replace("Z", "+00:00"))
    assert timedelta(days=2) <= created - calendar < timedelta(days=2, minutes=1), (created, calendar)
    assert timedelta(days=2) <= clock.now() - calendar.replace(tzinfo=None) < timedelta(days=2, minutes=1)


def test_an_extension_lets_one_student_submit_after_the_close(api):
    aid = create(api, open_at=at(-3), due_at=at(-2), hard_close_at=at(-1)).json()["id"]
    granted = api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"),
                              json={"student": "alice", "due_at": at(1), "hard_close_at": at(2)})
    assert granted.status_code == 201, granted.text
    assert granted.json()["granted_by"] == "prof" and granted.json()["student"] == "alice"
    ok = submit(api, aid)
    assert ok.status_code == 202 and ok.json()["late_seconds"] == 0
    refused(submit(api, aid, who="bob"), "closed at")


@pytest.mark.parametrize("who, payload, status, field", [
    ("alice", {"student": "alice", "due_at": at(1), "hard_close_at": at(2)}, 403, None),
    ("prof", {"student": "nobody", "due_at": at(1), "hard_close_at": at(2)}, 422, "student"),
    ("prof", {"student": "prof", "due_at": at(1), "hard_close_at": at(2)}, 422, "student"),
    ("prof", {"student": "alice", "due_at": at(2), "hard_close_at": at(1)}, 422, "hard_close_at"),
    ("eve", {"student": "alice", "due_at": at(1), "hard_close_at": at(2)}, 404, None),
])
def test_extensions_are_an_instructors_for_a_student_of_the_course(api, who, payload, status, field):
    aid = create(api).json()["id"]
    response = api.client.post(f"/v1/assignments/{aid}/extensions", json=payload, headers=api.as_(who))
    assert response.status_code == status, response.text
    if field:
        assert response.json()["errors"][0]["field"] == field


def grades_csv(api, aid, who="prof"):
    import csv
    import io

    response = api.client.get(f"/v1/assignments/{aid}/grades.csv", headers=api.as_(who))
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/csv")
    return list(csv.DictReader(io.StringIO(response.text)))


def test_a_late_attempt_is_penalized_per_day_and_the_export_shows_raw_beside_counted(api):
    aid = create(api, due_at=at(hours=-2), hard_close_at=at(1), late_penalty_per_day=0.1).json()["id"]
    sub = submit(api, aid).json()
    assert submit(api, aid, who="bob").status_code == 202
    (alice, bob) = grades_csv(api, aid)
    assert (alice["student"], alice["raw_score"], alice["penalty"], alice["counted_score"]) == ("alice", "8", "0.1",
                                                                                                 "7.2")
    assert (alice["attempt"], alice["submission_id"], alice["max_score"]) == ("1", str(sub["id"]), "8")
    assert alice["submitted_at_utc"].endswith("+00:00") and int(alice["late_seconds"]) >= 7200
    assert bob["student"] == "bob"
    listed = api.client.get(f"/v1/assignments/{aid}/grades", headers=api.as_("prof")).json()
    assert listed[0]["counted_score"] == 7.2 and listed[0]["raw_score"] == 8


def test_the_penalty_counts_each_started_day_and_stops_at_the_cap():
    from grader.services.setup.assignments import penalty_fraction
    from grader.core.models import Assignment

    a = Assignment(late_penalty_per_day=0.25, late_penalty_cap=0.6)
    assert [penalty_fraction(a, s) for s in (0, 1, 86400, 86401, 3 * 86400)] == [0.0, 0.25, 0.25, 0.5, 0.6]
    assert penalty_fraction(Assignment(late_penalty_per_day=0.5, late_penalty_cap=None), 10 * 86400) == 1.0


@pytest.mark.parametrize("counted, attempt, raw", [("latest", "2", "7"), ("best", "1", "8")])
def test_the_counted_attempt_is_the_latest_or_the_best(api, counted, attempt, raw):
    aid = create(api, counted_attempt=counted).json()["id"]
    assert submit(api, aid).status_code == 202
    worse = checkpoint_sheet()
    worse["answers"]["C2"]["reason"] = "it_is_valid"
    assert submit(api, aid, sheet=worse).json()["attempt"] == 2
    (row,) = grades_csv(api, aid)
    assert (row["attempt"], row["raw_score"], row["counted_score"]) == (attempt, raw, raw)


def test_only_instructors_export(api):
    aid = create(api).json()["id"]
    for who, status in (("alice", 403), ("tess", 403), ("eve", 404)):
        assert api.client.get(f"/v1/assignments/{aid}/grades.csv", headers=api.as_(who)).status_code == status


@pytest.mark.parametrize("visibility", ["after_due", "on_release"])
def test_scores_and_feedback_are_withheld_from_the_student_until_visible(api, visibility):
    aid = create(api, visibility=visibility).json()["id"]
    row = submit(api, aid).json()
    assert row["status"] == "graded" and row["total"] is None  # not even in the creation answer
    sid = row["id"]
    grade = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice"))
    assert grade.status_code == 409 and "withheld" in grade.json()["detail"]
    assert api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("alice")).status_code == 409
    assert api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()["total"] is None
    assert [s["total"] for s in api.client.get("/v1/submissions", headers=api.as_("alice")).json()] == [None]
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice"))
    assert page.status_code == 200 and "C2" not in page.text and "credit" not in page.text
    assert api.client.get(f"/submissions/{sid}/results.json", headers=api.as_("alice")).status_code == 404
    # Staff see it all along.
    assert api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("prof")).json()["total"] == 8
    assert "C2" in api.client.get(f"/submissions/{sid}", headers=api.as_("prof")).text
    if visibility == "on_release":
        assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("alice")).status_code == 403
        released = api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof"))
        assert released.status_code == 200 and released.json()["released_at"]
    else:  # the due date moves into the past for alice: an extension is the student's own due date
        api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"),
                        json={"student": "alice", "due_at": at(hours=-1), "hard_close_at": at(1)})
    grade = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice"))
    assert grade.status_code == 200 and grade.json()["total"] == 8


ROSTER = "student_id,name,email\ns1001,Ada Lovelace,ada@example.edu\ns1002,Alan Turing,alan@example.edu\n"


def roster(api, text, who="prof", course="l03"):
    return api.client.post(f"/v1/courses/{course}/roster", json={"csv": text}, headers=api.as_(who))


def test_a_roster_import_issues_each_new_student_one_token_and_a_reimport_duplicates_nobody(api):
    first = roster(api, ROSTER)
    assert first.status_code == 200, first.text
    tokens = {e["student"]: e["token"] for e in first.json()}
    assert set(tokens) == {"s1001", "s1002"} and all(tokens.values())
    ada = {"Authorization": f"Bearer {tokens['s1001']}"}
    assert api.client.get("/v1/courses/l03/assignments", headers=ada).status_code == 200  # the token works
    again = roster(api, ROSTER.replace("Alan Turing", "A. M. Turing") + "s1003,Grace Hopper,grace@example.edu\n")
    assert [(e["student"], e["created"], e["token"] is None, e["name"]) for e in again.json()] == [
        ("s1001", False, True, "Ada Lovelace"), ("s1002", False, True, "A. M. Turing"),
        ("s1003", True, False, "Grace Hopper")]
    from grader.core.db import new_session
    from grader.core.models import ApiToken, User

    with new_session() as session:
        assert session.scalar(select(func.count()).select_from(User).where(User.name.like("s100%"))) == 3
        assert session.scalar(select(func.count()).select_from(ApiToken)) == 5 + 3  # the fixture's 5 people + 3


GOOD = "student_id,name,email\nok1,Fine,fine@x.org\n"  # line 2: a good row that must not be stored either


@pytest.mark.parametrize("text, field, rule", [
    ("id,name,email\nok1,Fine,fine@x.org\n", "csv.line 1", "header must be student_id,name,email"),
    (GOOD + "s1,A,not-an-email\n", "csv.line 3.email", "email address"),
    (GOOD + "ok1,B,b@x.org\n", "csv.line 3.student_id", "twice"),
    (GOOD + "bad id,A,a@x.org\n", "csv.line 3.student_id", "letters, digits"),
    (GOOD + "s1,A\n", "csv.line 3", "3 columns"),
    (GOOD + "prof,P,p@x.org\n", "csv.student_id prof", "staff"),
    ("student_id,name,email\n", "csv", "no student rows"),
])
def test_a_bad_roster_is_refused_whole_naming_line_and_rule(api, text, field, rule):
    response = roster(api, text)
    assert response.status_code == 422, response.text
    assert any(e["field"] == field and rule in e["rule"] for e in response.json()["errors"]), response.json()
    from grader.core.db import new_session
    from grader.core.models import User

    with new_session() as session:  # not even the good row was stored
        assert session.scalar(select(func.count()).select_from(User).where(User.name == "ok1")) == 0


def test_only_an_instructor_imports_a_roster(api):
    assert roster(api, ROSTER, who="alice").status_code == 403
    assert roster(api, ROSTER, who="tess").status_code == 403
    assert roster(api, ROSTER, who="eve").status_code == 404


def test_two_submissions_racing_for_one_attempt_number_let_one_in(api, monkeypatch):
    from grader.services.setup import assignments

    aid = create(api, max_attempts=3).json()["id"]
    assert submit(api, aid).status_code == 202
    # The second request counted its attempts before the first one committed: both think they are attempt 1.
    monkeypatch.setattr(assignments, "attempts_used", lambda **_: 0)
    refused(submit(api, aid), "attempt 1 of “", "was just taken")
    assert stored() == (1, 7)
