"""Every page route that changes state, posted by each role that may not use it, changes nothing (issue 37, item 3).

The routes come from the app itself (`iter_route_contexts`), so a new one fails the first test until it is entered
in ROUTES with who may use it. Each route is then posted, with a request its own users would have taken, by every
other person: a student of the course (alice, whose submission it is, or bob), the course's auditor (tess, the staff
member who may read but not change), another course's instructor (eve) and nobody signed in. The whole database and
the tasks sent stay as they were; the same request from one who may use it then changes something, so the refusals
are about the role and not a malformed request. On the real app in-process (tests/grader/conftest.py)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import timedelta

import pytest
import yaml
from sqlalchemy import select

from tests.factories import reference_sheet, rubric_v3
from tests.notebooks import as_bytes, filled
from tests.grader.services.setup.test_assignments import ROSTER, at, create
from tests.grader.services.test_integrity_gaps import checkpoint_report, graded

PEOPLE = ("alice", "bob", "tess", "prof", "eve", None)  # None: nobody signed in
INSTRUCTOR = frozenset({"prof"})
STAFF = frozenset({"prof", "tess"})
COURSE_WRITERS = frozenset({"alice", "bob", "prof"})  # who fills the course's sheet forms (not an auditor)
WRITERS = COURSE_WRITERS | {"eve"}  # a free sheet is each writer's own, in their own course
ANYONE = frozenset(PEOPLE)


@dataclass
class World:
    """The objects of course l03 a route acts on, made through the API as their users would."""

    assignment: int
    submission: int  # alice's, graded
    review_request: int  # alice's, about C2
    failed_run: int  # a run of alice's free submission that failed (resendable)
    done_run: int  # another, done (an audit re-run's source)
    regrade_hash: str  # the preview's content hash of v3, published for the regrade
    draft_form: dict = field(default_factory=dict)  # the rubric draft page's form, one tolerance changed
    unpooled: int = 0  # an assignment opening in an hour, without a variant pool yet
    pooled: int = 0  # one opening in an hour whose pool is ready with one of its two variants dropped (to top up)


def _at(days: float) -> str:
    from grader.core.models import utcnow

    return (utcnow() + timedelta(days=days)).strftime("%Y-%m-%dT%H:%M")  # a datetime-local field, course zone UTC


def make_world(api) -> World:
    from grader.core.db import new_session
    from grader.core.models import CaseRun
    from tests.grader.services.rubrics.test_tolerance_review import _draft_form

    aid = create(api).json()["id"]
    sid = graded(aid, checkpoint_report({"C2": "no_credit"}))
    asked = api.client.post(f"/v1/submissions/{sid}/review-requests", headers=api.as_("alice"),
                            json={"item_id": "C2", "message": "My reason for C2 names the measured duration."})
    assert asked.status_code == 201, asked.text
    extension = api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"),
                                json={"student": "bob", "due_at": _iso(4), "hard_close_at": _iso(5)})
    assert extension.status_code in (200, 201), extension.text
    free = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert free.status_code == 202, free.text
    with new_session() as session:
        runs = session.scalars(select(CaseRun).where(CaseRun.submission_id == free.json()["id"])
                               .order_by(CaseRun.name)).all()
        runs[0].status, runs[0].error = "failed", "worker lost"
        runs[1].status, runs[1].result_status, runs[1].actual_backend = "done", "ok", "cpu"
        failed, done = runs[0].id, runs[1].id
        session.commit()
    draft = _draft_form(api)
    draft |= {"value.proxy_resolution": "0.001", "rationale.proxy_resolution": "reviewed for the page roles test"}
    assert api.client.post("/v1/rubrics/versions", json=rubric_v3(), headers=api.as_("prof")).status_code == 201
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    draft["version"] = "4"  # v3 is the one just published
    return World(aid, sid, asked.json()["id"], failed, done, preview["content_hash"], draft, *_pool_assignments(api))


def _pool_assignments(api) -> tuple[int, int]:
    """Two assignments opening in an hour: one without a pool, one whose pool of two is ready, one variant dropped."""
    from grader.core.db import new_session
    from grader.core.models import Assignment, User
    from grader.core.variants import decide
    from grader.services.setup import variants

    unpooled, pooled = (create(api, part="sheet", title=title, open_at=at(hours=1)).json()["id"]
                        for title in ("Own lab", "Own lab, pooled"))
    with new_session() as session:
        prof = session.scalar(select(User).where(User.name == "prof"))
        pool = variants.generate(session=session, assignment=session.get(Assignment, pooled), user=prof, seed=7, k=2)
        for row, kept in zip(pool.variants, (True, False)):
            decide(session, row, kept=kept, reason=None if kept else "lab check failed: substeps_reduce_proxy")
        session.commit()
    return unpooled, pooled


def _iso(days: float) -> str:
    from grader.core.models import utcnow

    return (utcnow() + timedelta(days=days)).replace(microsecond=0).isoformat() + "Z"


@dataclass(frozen=True)
class Route:
    allowed: frozenset
    request: Callable[[World], tuple[str, dict | None, dict | None]] | None = None  # url, form data, files
    changes: bool = True  # whether the allowed request changes stored state in this world


def assignment_form(**fields) -> dict:
    """The set-up page's assignment form as an instructor fills it."""
    return {"lesson": "L03", "open_at": _at(-1), "due_at": _at(2), "hard_close_at": _at(3),
            "counted_attempt": "latest", "visibility": "immediate"} | fields


SHEET_YAML = {"file": ("sheet.yaml", yaml.safe_dump(reference_sheet()).encode(), "application/yaml")}
# The template notebook filled with the reference answers (issue 48's upload on the sheet page)
SHEET_NOTEBOOK = {"file": ("sheet.ipynb", as_bytes(filled(reference_sheet())), "application/x-ipynb+json")}
# the route's assignment holds the checkpoints alone: a notebook with their cells only, filled
_CHECKPOINTS = {k: v for k, v in reference_sheet().items() if k != "configs"}
_CHECKPOINTS["answers"] = {k: v for k, v in _CHECKPOINTS["answers"].items() if k.startswith("C")}
_CHECKPOINT_CELLS = {"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": [
    {"cell_type": "code", "id": f"answer-{k}", "metadata": {"tags": [f"answer:{k}"]}, "source": "",
     "outputs": [], "execution_count": None} for k in _CHECKPOINTS["answers"]]}
CHECKPOINT_NOTEBOOK = {"file": ("sheet.ipynb", as_bytes(filled(_CHECKPOINTS, notebook=_CHECKPOINT_CELLS)),
                                "application/x-ipynb+json")}

ROUTES: dict[str, Route] = {
    # Anyone: the authority is what is posted, not who posts it (a token, a link's secret, the platform's signed
    # launch and its state: tests/grader/services/identity/test_sessions.py, test_sign_in_links.py, test_lti.py), or nothing is stored.
    "/sign-in": Route(ANYONE),
    "/sign-out": Route(ANYONE),
    "/language": Route(ANYONE),
    "/sign-in/link/{secret}": Route(ANYONE),
    "/lti/login": Route(ANYONE),
    "/lti/launch": Route(ANYONE),
    "/lti/deep-link": Route(ANYONE),
    # The course's instructors.
    "/courses/{course}/regrade": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/regrade", {"version": "3", "lesson": "L03", "content_hash": w.regrade_hash}, None)),
    # Sends what is due to the LMS: with no gradebook in this world the instructor's press stores nothing either.
    "/courses/{course}/lti/retry": Route(INSTRUCTOR, lambda w: ("/courses/l03/lti/retry", {}, None), changes=False),
    "/courses/{course}/rubrics/{lesson}/{version}/signoff": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/rubrics/L03/2/signoff", {"note": "checked against the audit log"}, None)),
    "/courses/{course}/rubrics/{lesson}/{version}/draft": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/rubrics/L03/2/draft", w.draft_form, None)),
    "/courses/{course}/dashboard/case-runs/{case_run_id}/resend": Route(INSTRUCTOR, lambda w: (
        f"/courses/l03/dashboard/case-runs/{w.failed_run}/resend", {}, None)),
    "/assignments/{assignment_id}/release": Route(INSTRUCTOR, lambda w: (
        f"/assignments/{w.assignment}/release", {}, None)),
    "/assignments/{assignment_id}/extensions": Route(INSTRUCTOR, lambda w: (
        f"/assignments/{w.assignment}/extensions", {"student": "alice", "due_at": _at(3), "hard_close_at": _at(4)},
        None)),
    "/assignments/{assignment_id}/extensions/revoke": Route(INSTRUCTOR, lambda w: (
        f"/assignments/{w.assignment}/extensions/revoke", {"student": "bob"}, None)),
    "/assignments/{assignment_id}/variants": Route(INSTRUCTOR, lambda w: (
        f"/assignments/{w.unpooled}/variants", {"seed": "7", "k": "2"}, None)),
    "/assignments/{assignment_id}/variants/top-up": Route(INSTRUCTOR, lambda w: (
        f"/assignments/{w.pooled}/variants/top-up", {}, None)),
    "/assignments/{assignment_id}/edit": Route(INSTRUCTOR, lambda w: (
        f"/assignments/{w.assignment}/edit", assignment_form(title="Checkpoints, renamed", part="checkpoints"), None)),
    "/courses/{course}/reviews/{request_id}/answer": Route(INSTRUCTOR, lambda w: (
        f"/courses/l03/reviews/{w.review_request}/answer", {"answer": "Your reason holds.", "score": "1"}, None)),
    "/submissions/{submission_id}/overrides": Route(INSTRUCTOR, lambda w: (
        f"/submissions/{w.submission}/overrides", {"item_id": "C2", "score": "1", "comment": "The reason holds."},
        None)),
    "/courses/{course}/setup/timezone": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/setup/timezone", {"timezone": "Europe/Berlin"}, None)),
    "/courses/{course}/setup/free-submissions": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/setup/free-submissions", {"other": ""}, None)),  # unchecked: refused
    "/courses/{course}/setup/roster": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/setup/roster", {}, {"csv": ("roster.csv", ROSTER.encode(), "text/csv")})),
    "/courses/{course}/setup/students/{student}/sign-in-link": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/setup/students/alice/sign-in-link", {}, None)),
    "/courses/{course}/setup/assignments": Route(INSTRUCTOR, lambda w: (
        "/courses/l03/setup/assignments", assignment_form(title="Exercises", part="exercises"), None)),
    # The course's staff: instructors and auditors ask for audit re-runs.
    "/audit/reruns": Route(STAFF, lambda w: ("/audit/reruns", {"case_run_id": str(w.done_run)}, None)),
    # The submission's own student.
    "/submissions/{submission_id}/review-requests": Route(frozenset({"alice"}), lambda w: (
        f"/submissions/{w.submission}/review-requests", {"item_id": "C3", "message": "Please look at C3."}, None)),
    # Whoever fills the course's sheets (its students and instructors), and anyone's own free sheet.
    "/assignments/{assignment_id}/sheet": Route(COURSE_WRITERS, lambda w: (
        f"/assignments/{w.assignment}/sheet", {"action": "save", "student": "alice"}, None)),
    "/assignments/{assignment_id}/sheet/draft": Route(COURSE_WRITERS, lambda w: (
        f"/assignments/{w.assignment}/sheet/draft", {"student": "alice"}, None)),
    "/assignments/{assignment_id}/sheet/import": Route(COURSE_WRITERS, lambda w: (
        f"/assignments/{w.assignment}/sheet/import", {}, SHEET_YAML)),
    "/sheet": Route(WRITERS, lambda w: ("/sheet", {"action": "save", "student": "alice"}, None)),
    "/sheet/draft": Route(WRITERS, lambda w: ("/sheet/draft", {"student": "alice"}, None)),
    "/sheet/import": Route(WRITERS, lambda w: ("/sheet/import", {}, SHEET_YAML)),
    "/assignments/{assignment_id}/sheet/notebook": Route(COURSE_WRITERS, lambda w: (
        f"/assignments/{w.assignment}/sheet/notebook", {}, CHECKPOINT_NOTEBOOK)),
    "/sheet/notebook": Route(WRITERS, lambda w: ("/sheet/notebook", {}, SHEET_NOTEBOOK)),
}


def state_changing_page_routes() -> set[str]:
    from fastapi.routing import iter_route_contexts

    from grader.main import app

    return {route.path for route in iter_route_contexts(app.routes)
            if set(route.methods or ()) - {"GET", "HEAD", "OPTIONS"} and not route.path.startswith("/v1")}


def test_every_state_changing_page_route_says_who_may_use_it():
    routes = state_changing_page_routes()
    assert routes - ROUTES.keys() == set(), "page routes missing from ROUTES (say who may use them)"
    assert ROUTES.keys() - routes == set(), "ROUTES names routes the app no longer has"
    assert all(route.request is not None for route in ROUTES.values() if route.allowed != ANYONE)


def snapshot(api) -> dict:
    """Every row of every table, and the tasks sent: what a refused request must leave as it was."""
    from grader.core.db import new_session
    from grader.core.models import Base

    with new_session() as session:
        rows = {table.name: sorted(map(repr, session.execute(select(table)).all()))
                for table in Base.metadata.sorted_tables}
    return {"rows": rows, "sent": list(api.sent)}


def changed(before: dict, after: dict) -> list[str]:
    return [name for name in before["rows"] if before["rows"][name] != after["rows"][name]] + (
        ["sent tasks"] if before["sent"] != after["sent"] else [])


def post_as(api, who: str | None, url: str, data: dict | None, files: dict | None):
    api.client.cookies.clear()
    return api.client.post(url, data=data, files=files, headers=api.as_(who) if who else {}, follow_redirects=False)


@pytest.mark.parametrize("path", [p for p, r in ROUTES.items() if r.allowed != ANYONE])
def test_a_page_route_changes_nothing_for_anyone_who_may_not_use_it(api, path):
    route = ROUTES[path]
    world = make_world(api)
    url, data, files = route.request(world)
    for who in PEOPLE:
        if who in route.allowed:
            continue
        before = snapshot(api)
        answer = post_as(api, who, url, data, files)
        assert answer.status_code < 500, (who, answer.status_code, answer.text[:500])
        assert answer.status_code not in (200, 201), (who, answer.status_code)  # no page of a done action
        assert changed(before, snapshot(api)) == [], (who, answer.status_code)
    who = sorted(route.allowed, key=PEOPLE.index)[0]
    before = snapshot(api)
    answer = post_as(api, who, url, data, files)
    assert answer.status_code < 400, (who, answer.status_code, answer.text[:800])
    assert bool(changed(before, snapshot(api))) is route.changes, (who, changed(before, snapshot(api)))
