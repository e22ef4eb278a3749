"""The class dashboard for an assignment on per-student variants (issue 34), on the in-process app (SQLite), its
rows made directly: the copy evidence (student, submission, own variant, the variant the answers fit, the items;
the grade unchanged), the counted sheets grouped by variant (n, mean, per item), and a pool's measuring submissions
left out of every count, list and distribution of the students' work (their stuck runs listed as the pool's)."""

from __future__ import annotations

import pytest
from sqlalchemy import select

from grader.core.models import (CaseRun, CopyFlag, Grade, PoolVariant, Submission, User, VariantPool, utcnow)
from tests.grader.services.reports.test_dashboard import _report, _session
from tests.grader.services.setup.test_variants import pool_assignment

PAIRS = {"baseline_low": 0.5, "baseline_high": 0.8, "modified_low": 0.3, "modified_high": 0.8}
STOPS = {f"{run}_{lane}_stop_distance_m": 0.3 for run in ("baseline", "modified") for lane in ("low", "high")}
H1 = {"baseline": {"low": 0.5, "high": 0.8}, "modified": {"low": 0.3, "high": 0.8}}
H4 = {run: {lane: {"value": 30.0, "unit": "cm"} for lane in ("low", "high")} for run in ("baseline", "modified")}


def _graded(session, *, student: User, variant: PoolVariant, assignment_id: int | None, attempt: int | None,
            h4_verdict: str) -> Submission:
    submission = Submission(course_id=student.course_id, student_id=student.id, lesson="L03", sheet={},
                            status="graded", assignment_id=assignment_id, attempt=attempt, late_seconds=0,
                            variant_id=variant.id)
    session.add(submission)
    session.flush()
    report = _report(student.name, H1, H4, PAIRS, STOPS, h4_verdict=h4_verdict)
    session.add(Grade(submission_id=submission.id, rubric_lesson="L03", rubric_version="2", rubric_hash="x",
                      total=report["total"], max_total=2, report=report))
    session.flush()
    return submission


@pytest.fixture
def variant_class(api):
    """An assignment with a ready pool (v5-1 and v5-2 kept, v5-3 dropped): the instructor's measuring submission of
    v5-1 graded, another with a failed run; alice on v5-1 (2 of 2), bob on v5-2 (1 of 2) flagged as fitting v5-1 on
    H1 and H4 (and an older flag against a grade since superseded)."""
    aid = pool_assignment(api)
    with _session() as session:
        people = {u.name: u for u in session.scalars(select(User))}
        pool = VariantPool(assignment_id=aid, lesson="L03", space_version="1", space_hash="h", rubric_version="2",
                           seed=5, k=3, state="ready", rejected=[], created_by_id=people["prof"].id, ready_at=utcnow())
        session.add(pool)
        session.flush()
        v1, v2, v3 = (PoolVariant(pool_id=pool.id, name=f"v5-{n}", position=n, parameters={}, digest=str(n),
                                  state=state) for n, state in ((1, "kept"), (2, "kept"), (3, "dropped")))
        session.add_all([v1, v2, v3])
        session.flush()
        measuring = _graded(session, student=people["prof"], variant=v1, assignment_id=None, attempt=None,
                            h4_verdict="credit")
        stuck = Submission(course_id=people["prof"].course_id, student_id=people["prof"].id, lesson="L03", sheet={},
                           status="failed", variant_id=v2.id)
        session.add(stuck)
        session.flush()
        session.add(CaseRun(submission_id=stuck.id, name="N1", kind="contact", backend="cpu", precision="32",
                            spec={}, status="failed", error="case process timed out after 600 s",
                            finished_at=utcnow()))
        v1.submission_id, v2.submission_id = measuring.id, stuck.id
        alice = _graded(session, student=people["alice"], variant=v1, assignment_id=aid, attempt=1,
                        h4_verdict="credit")
        bob = _graded(session, student=people["bob"], variant=v2, assignment_id=aid, attempt=1,
                      h4_verdict="no_credit")
        current = session.scalar(select(Grade).where(Grade.submission_id == bob.id))
        old = Grade(submission_id=bob.id, rubric_lesson="L03", rubric_version="2", rubric_hash="x", total=0,
                    max_total=2, report=current.report, superseded_at=utcnow())
        session.add(old)
        session.flush()
        for grade, items in ((current, ["H1", "H4"]), (old, ["C1", "C5"])):
            session.add(CopyFlag(submission_id=bob.id, grade_id=grade.id, variant_id=v1.id, items=items,
                                 own_expected={i: f"own {i}" for i in items},
                                 other_expected={i: f"other {i}" for i in items}, summary="answers fit v5-1"))
        session.commit()
        return {"aid": aid, "alice": alice.id, "bob": bob.id, "measuring": measuring.id, "stuck": stuck.id}


def test_copy_flags_and_scores_per_variant_are_on_the_dashboard(api, variant_class):
    data = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("tess")).json()
    (av,) = data["variants"]
    assert av["id"] == variant_class["aid"] and av["page"] == f"/assignments/{variant_class['aid']}"
    (flag,) = av["flags"]  # the current grade's only: the superseded grade's flag is history
    assert (flag["student"], flag["submission_id"], flag["own_variant"], flag["fits_variant"], flag["items"]) == (
        "bob", variant_class["bob"], "v5-2", "v5-1", ["H1", "H4"])
    scores = {v["variant"]: v for v in av["variants"]}
    assert list(scores) == ["v5-1", "v5-2"]  # the dropped variant has no student: not listed
    assert (scores["v5-1"]["n"], scores["v5-1"]["mean"], scores["v5-2"]["n"], scores["v5-2"]["mean"]) == (1, 2, 1, 1)
    assert scores["v5-1"]["items"] == {"H1": 1, "H4": 1} and scores["v5-2"]["items"] == {"H1": 1, "H4": 0}
    assert (av["n"], av["mean"], scores["v5-2"]["difference"]) == (2, 1.5, -0.5)

    page = api.client.get("/courses/l03/dashboard", headers=api.as_("prof"))
    assert page.status_code == 200
    text = page.text
    row = text.split(f'id="copy-flag-{variant_class["bob"]}-v5-1"')[1].split("</tr>")[0]
    assert f'<a href="/submissions/{variant_class["bob"]}">' in row and "v5-2" in row and "<strong>H4</strong>" in row
    assert "v5-2 expects own H4; v5-1 expects other H4" in row and "C5" not in row
    scores_row = text.split(f'id="variant-scores-{variant_class["aid"]}-v5-2"')[1].split("</tr>")[0]
    assert "1.00 / 2" in scores_row and "-0.50" in scores_row
    h4_row = text.split(f'id="variant-items-{variant_class["aid"]}-H4"')[1].split("</tr>")[0]
    assert [c.split(">")[-1] for c in h4_row.split("</td>")[:-1]] == ["1", "1.00", "0.00"]  # points, v5-1, v5-2
    # the grade stands: the flag changed nothing
    with _session() as session:
        assert session.scalar(select(Grade.total).where(Grade.submission_id == variant_class["bob"],
                                                        Grade.superseded_at.is_(None))) == 1


def test_measuring_submissions_are_no_students_work_on_the_dashboard(api, variant_class):
    data = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
    assert {r["student"] for r in data["roster"]} == {"alice", "bob"}
    assert sum(data["submissions_by_state"].values()) == 2 and data["submissions_by_state"] == {"graded": 2}
    assert sum(data["submissions_per_day"].values()) == 2
    assert data["analysis"]["n_reports"] == 2
    assert {r["student"] for p in data["predictions"] for r in p["rows"]} == {"alice", "bob"}
    assert [g["n"] for g in data["score_groups"]] == [2]  # the assignment's; no "outside assignments" group
    # a pool's failed run is still the instructor's to re-send, named by the variant it measures
    (problem,) = data["problems"]
    assert problem["submission_id"] == variant_class["stuck"] and problem["measures_variant"] == "v5-2"
    text = api.client.get("/courses/l03/dashboard", headers=api.as_("prof")).text
    assert "measures variant v5-2" in text
    assert f'/submissions/{variant_class["measuring"]}"' not in text


@pytest.mark.parametrize("who, code", [("alice", 404), ("eve", 404)])
def test_the_evidence_is_the_courses_staffs_only(api, variant_class, who, code):
    assert api.client.get("/courses/l03/dashboard", headers=api.as_(who)).status_code == code
    assert api.client.get("/v1/courses/l03/dashboard", headers=api.as_(who)).status_code in (403, 404)
