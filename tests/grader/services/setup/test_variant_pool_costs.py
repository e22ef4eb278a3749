"""What a variant pool costs is counted against the instructor and the course (issue 44), on the in-process app
(SQLite, enqueueing recorded with its priority): K is capped by a setting (422), pools measured at once are capped per
instructor and per course (429 with Retry-After, nothing stored), a pool's runs are sent and re-sent (the reconciler,
an instructor's re-send) at the lowest priority, behind a student's, and its page says how many of its runs wait and
what it cost so far, in English and Chinese. The order a real broker serves them in: tests/integration/
test_variant_pool_queue.py."""

from __future__ import annotations

from datetime import timedelta

from sqlalchemy import func, select, update

from tests.factories import reference_sheet
from tests.grader.pages.test_setup_pages import page_post
from tests.grader.services.setup.test_assignments import at, create
from tests.grader.services.setup.test_variants import generate, pool_assignment


def stored_pools() -> tuple[int, int]:
    """(pools, case runs) stored."""
    from grader.core.db import new_session
    from grader.core.models import CaseRun, VariantPool

    with new_session() as session:
        return (session.scalar(select(func.count()).select_from(VariantPool)),
                session.scalar(select(func.count()).select_from(CaseRun)))


def instructor(api, name: str) -> None:
    """Another instructor of course l03, with an API token."""
    from grader.core.db import new_session
    from grader.services.identity import accounts

    with new_session() as session:
        course = accounts.get_or_create_course(session=session, name="l03")
        user = accounts.get_or_create_user(session=session, course=course, name=name, role="instructor")
        api.tokens[name] = accounts.create_token(session=session, user=user)
        session.commit()


def ready(assignment_id: int) -> None:
    """Every variant of the assignment's pool kept, as its lab check would decide: the pool is ready."""
    from grader.core.db import new_session
    from grader.core.models import PoolVariant, VariantPool
    from grader.core.variants import decide

    with new_session() as session:
        for row in session.scalars(select(PoolVariant).join(VariantPool)
                                   .where(VariantPool.assignment_id == assignment_id)):
            decide(session, row, kept=True, reason=None)
        session.commit()


def test_k_past_the_services_limit_is_refused_naming_the_field_and_the_limit(api, monkeypatch):
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "variant_pool_k_max", 8)
    assignment_id = pool_assignment(api)
    refused = generate(api, assignment_id, k=9)
    assert refused.status_code == 422, refused.text
    (error,) = refused.json()["errors"]
    assert error["field"] == "k" and "between 1 and 8 variants" in error["rule"], error
    assert "variant_pool_k_max" in error["rule"]
    assert stored_pools() == (0, 0) and api.sent == []
    # the page's form says the same bound and refuses past it in its own words
    form = api.client.get(f"/assignments/{assignment_id}", headers=api.as_("prof")).text
    assert 'name="k" min="1" max="8"' in form
    typed = page_post(api, f"/assignments/{assignment_id}/variants", {"seed": "7", "k": "9"})
    assert typed.status_code == 422 and "a whole number from 1 to 8" in typed.text
    assert stored_pools() == (0, 0)
    assert generate(api, assignment_id, k=8).status_code == 201


def test_pools_measured_at_once_are_capped_per_instructor_and_per_course(api, monkeypatch):
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "variant_pools_measuring_per_instructor", 1)
    monkeypatch.setattr(settings, "variant_pools_measuring_per_course", 2)
    instructor(api, "pat")
    instructor(api, "quinn")
    first, second, third = (create(api, part="sheet", title=title, open_at=at(hours=1)).json()["id"]
                            for title in ("Lab A", "Lab B", "Lab C"))
    assert generate(api, first, k=2).status_code == 201
    pools, runs = stored_pools()

    mine = generate(api, second, k=2)
    assert mine.status_code == 429 and int(mine.headers["Retry-After"]) > 0, mine.text
    (error,) = mine.json()["errors"]
    assert error["field"] == "assignment" and "variant_pools_measuring_per_instructor" in error["rule"], error
    assert "at most 1 variant pool measured at once per instructor" in error["rule"] and "“Lab A”" in error["rule"]
    assert stored_pools() == (pools, runs)
    # the page shows the refusal in its reader's words, in English and in Chinese
    page = page_post(api, f"/assignments/{second}/variants", {"seed": "7", "k": "2"})
    assert page.status_code == 429 and "At most 1 variant pool is measured at once per instructor" in page.text
    assert "“Lab A”" in page.text
    chinese = page_post(api, f"/assignments/{second}/variants", {"seed": "7", "k": "2"}, Cookie="grader_lang=zh")
    assert chinese.status_code == 429 and "每位教师同时最多测量 1 个变体池" in chinese.text
    assert stored_pools() == (pools, runs)

    assert generate(api, second, who="pat", k=2).status_code == 201  # another instructor: the course has room
    course = generate(api, third, who="quinn", k=2)
    assert course.status_code == 429 and course.headers["Retry-After"], course.text
    (error,) = course.json()["errors"]
    assert "at most 2 variant pools measured at once per course" in error["rule"], error
    assert "variant_pools_measuring_per_course" in error["rule"] and "“Lab A”, “Lab B”" in error["rule"]
    assert stored_pools()[0] == pools + 1

    ready(first)  # Lab A's variants are all kept or dropped: it no longer counts
    assert generate(api, third, k=2).status_code == 201
    # drawing a ready pool further measures it again: counted like a new one
    with_dropped = api.client.post(f"/v1/assignments/{first}/variants/top-up", headers=api.as_("prof"))
    assert with_dropped.status_code == 409  # nothing dropped: K kept already, refused before any cap
    from grader.core.db import new_session
    from grader.core.models import PoolVariant, VariantPool

    with new_session() as session:
        row = session.scalar(select(PoolVariant).join(VariantPool).where(VariantPool.assignment_id == first)
                             .order_by(PoolVariant.position))
        row.state, row.reason = "dropped", "lab check failed: by the test"
        session.commit()
    topped = api.client.post(f"/v1/assignments/{first}/variants/top-up", headers=api.as_("prof"))
    assert topped.status_code == 429 and "variant_pools_measuring_per_instructor" in topped.text, topped.text


def test_a_pools_runs_go_behind_a_students_when_sent_re_sent_or_predicted(api, monkeypatch):
    from grader import dispatch
    from grader.core.db import new_session
    from grader.core.lifecycle import COMPLETE_PRIORITY, POOL_PRIORITY, REQUEUED_PRIORITY
    from grader.core.models import CaseRun, PoolVariant, utcnow
    from grader.core.settings import settings
    from grader.reconcile import find_and_requeue
    from grader.services.submissions.progress import queue_order

    assignment_id = pool_assignment(api)
    assert generate(api, assignment_id, k=2).status_code == 201
    assert api.priorities == [POOL_PRIORITY] * 18 and POOL_PRIORITY >= COMPLETE_PRIORITY
    student = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert student.status_code == 202, student.text
    theirs = api.priorities[18:]
    assert len(theirs) == 9 and max(theirs) < POOL_PRIORITY
    with new_session() as session:
        pool_ids = [r.id for r in session.scalars(select(CaseRun).where(CaseRun.submission_id.in_(
            select(PoolVariant.submission_id))).order_by(CaseRun.id))]
        student_ids = [r.id for r in session.scalars(select(CaseRun).where(
            CaseRun.submission_id == student.json()["id"]).order_by(CaseRun.id))]
        assert queue_order(session, "cpu") == student_ids + pool_ids  # what the progress pages count ahead

        # Every run waits past the queue lease (the pool's behind students' runs, say): the reconciler re-sends the
        # student's ahead of the queue and the pool's behind every student's again.
        session.execute(update(CaseRun).values(
            queued_at=utcnow() - timedelta(seconds=settings.queue_lease_s + 1)))
        session.commit()
        resend = find_and_requeue(session=session)
    sent = len(api.sent)
    dispatch.resend(resend)
    again = {args[0]: priority for args, priority in zip(api.sent[sent:], api.priorities[sent:])}
    assert again == {**{i: REQUEUED_PRIORITY for i in student_ids}, **{i: POOL_PRIORITY for i in pool_ids}}

    # An instructor re-sends a failed run of the pool: behind students' runs too.
    with new_session() as session:
        run = session.get(CaseRun, pool_ids[0])
        run.status, run.result_status, run.error = "failed", "failed", "by the test"
        session.commit()
    sent = len(api.sent)
    resent = api.client.post(f"/v1/case-runs/{pool_ids[0]}/resend", headers=api.as_("prof"))
    assert resent.status_code == 202, resent.text
    assert [args[0] for args in api.sent[sent:]] == [pool_ids[0]] and api.priorities[sent:] == [POOL_PRIORITY]


def test_the_pool_page_says_how_many_of_its_runs_wait_and_what_they_cost(api):
    from grader.core.db import new_session
    from grader.core.models import CaseRun, PoolVariant

    assignment_id = pool_assignment(api)
    assert generate(api, assignment_id, k=2).status_code == 201
    listed = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("prof")).json()
    assert listed["runs"] == {"total": 18, "queued": 18, "running": 0, "finished": 0, "reused": 0, "case_s": 0.0,
                              "priority": 9}
    with new_session() as session:
        runs = session.scalars(select(CaseRun).where(CaseRun.submission_id.in_(select(PoolVariant.submission_id)))
                               .order_by(CaseRun.id)).all()
        runs[0].status = "running"
        for run, wall in zip(runs[1:4], (1.2, 2.6, None)):
            run.status, run.result_status, run.wall_s = "done", "ok", wall
        runs[3].reused_from_id = runs[1].id  # covered by a stored measurement: its case time is not this pool's
        runs[3].wall_s = 9.0
        session.commit()
    listed = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("prof")).json()
    assert listed["runs"] == {"total": 18, "queued": 14, "running": 1, "finished": 3, "reused": 1, "case_s": 3.8,
                              "priority": 9}

    english = api.client.get(f"/assignments/{assignment_id}", headers=api.as_("prof")).text
    line = english.split('<p id="pool-runs">')[1].split("</p>")[0]
    assert "Measuring it costs 18 case runs: 14 queued, 1 running now." in line
    assert "1 of them reused a stored measurement; the others took 3.8 s of case time so far." in line
    assert "behind every student's runs" in line
    chinese = api.client.get(f"/assignments/{assignment_id}", headers={**api.as_("prof"),
                                                                        "Cookie": "grader_lang=zh"}).text
    line = chinese.split('<p id="pool-runs">')[1].split("</p>")[0]
    assert "测量它共需 18 次案例运行：14 次排队中，1 次正在运行。" in line and "3.8 秒" in line


def test_a_worker_starting_where_one_died_resends_a_pool_run_behind_students_and_a_students_first(api, monkeypatch):
    """worker.tasks._rerun_what_died_here: a student's run its dead process held goes ahead of the queue, a pool's run
    behind every student's again."""
    import subprocess

    from grader.core import lifecycle
    from grader.core.db import new_session
    from grader.core.models import CaseRun, PoolVariant, utcnow
    from worker import tasks

    assert generate(api, pool_assignment(api), k=1).status_code == 201
    student = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert student.status_code == 202, student.text
    gone = subprocess.Popen(["true"])
    gone.wait()
    with new_session() as session:
        pool_run = session.scalar(select(CaseRun).where(CaseRun.submission_id.in_(select(PoolVariant.submission_id)))
                                  .order_by(CaseRun.id))
        student_run = session.scalar(select(CaseRun).where(CaseRun.submission_id == student.json()["id"])
                                     .order_by(CaseRun.id))
        for run in (pool_run, student_run):
            run.status, run.worker, run.worker_pid, run.started_at, run.tries = (
                "running", lifecycle.HOST, gone.pid, utcnow(), 1)
        session.commit()
        ids = pool_run.id, student_run.id
    sent = []
    monkeypatch.setattr(tasks.run_case_run, "apply_async", lambda **kwargs: sent.append(kwargs))
    tasks._rerun_what_died_here()
    assert sorted((s["args"][0], s["priority"]) for s in sent) == sorted(
        [(ids[0], lifecycle.POOL_PRIORITY), (ids[1], lifecycle.RERUN_PRIORITY)])
