"""A pool an instructor can rely on (issue 47), on the real stack (PostgreSQL, Redis, a Celery worker running Genesis on
CPU, the real HTTP app) in a real browser: the instructor asks for 6 kept variants on the assignment's page and gets 6
(the worker draws past any variant its lab check drops); students open the course page, which fixes their variants;
the instructor adds 4 more from the same page while students work; a student who comes later gets one of the new
variants, and the first students' labs are unchanged. The shipped variant space (the latest, v2) is used."""

from __future__ import annotations

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Assignment, StudentVariant, User
from tests.integration.a11y import assert_accessible
from tests.integration.helpers import SHOTS, at, wait_until

pytestmark = [pytest.mark.integration, pytest.mark.xdist_group("variants")]
COURSE = "l03-test"
SEED, K, MORE = 47, 6, 4


def signed_in(browser, stack, token: str):
    page = browser.new_page(viewport={"width": 1280, "height": 900})
    page.goto(f"{stack.url}/sign-in")
    page.fill("#token", token)
    page.click("form[action='/sign-in'] button[type=submit]")
    page.wait_for_selector("header .who")
    return page


def variant_of(stack, aid: int, name: str) -> str | None:
    with Session(stack.engine) as session:
        row = session.scalar(select(StudentVariant).join(User, StudentVariant.student_id == User.id)
                             .where(StudentVariant.assignment_id == aid, User.name == name))
        return row.variant.name if row else None


def ready_with(prof, aid: int, kept: int):
    return lambda: (p := prof.variants(aid))["state"] == "ready" and p["kept"] >= kept and p


def test_an_instructor_gets_k_kept_and_tops_the_live_pool_up_for_later_students(browser, stack):
    prof = stack.client("prof")
    aid = prof.create_assignment(COURSE, {"title": "Own lab (top-up)", "part": "sheet", "open_at": at(hours=1),
                                          "due_at": at(days=2), "hard_close_at": at(days=3)})["id"]
    names = [f"t47s{i}" for i in range(K + 1)]
    roster = "student_id,name,email\n" + "".join(f"{n},Student {n},{n}@example.edu\n" for n in names)
    tokens = {s["student"]: s["token"] for s in prof.import_roster(COURSE, roster, links=True)}

    page = signed_in(browser, stack, stack.tokens["prof"])
    page.goto(f"{stack.url}/assignments/{aid}")
    page.get_by_label("Seed").fill(str(SEED))
    page.get_by_label("Variants to keep (K)").fill(str(K))
    page.click("#generate-pool")
    page.wait_for_selector("#pool")
    pool = wait_until(ready_with(prof, aid, K), f"{K} variants kept")
    assert pool["kept"] == K and pool["k"] == K and pool["drawn"] <= pool["draw_budget"] == 2 * K, pool
    page.reload()
    assert f"Kept {K} of the {K} asked for, in {pool['drawn']} variants drawn." in page.inner_text("#pool-outcome")
    first_kept = {v["id"] for v in pool["variants"] if v["state"] == "kept"}

    # The assignment opens; six students open the course page, one on each kept variant (the pool is balanced).
    with Session(stack.engine) as session:
        row = session.get(Assignment, aid)
        row.open_at = row.open_at.replace(year=row.open_at.year - 1)
        session.commit()
    summaries = {}
    for name in names[:K]:
        student = signed_in(browser, stack, tokens[name])
        student.goto(f"{stack.url}/courses/{COURSE}")
        summaries[name] = student.inner_text(f"#assignment-{aid}-lab-summary")
        student.close()
    first = {name: variant_of(stack, aid, name) for name in names[:K]}
    assert set(first.values()) == first_kept, first

    # The instructor adds four more while the students work.
    page.reload()
    page.get_by_label("Variants more to keep").fill(str(MORE))
    page.click("#add-variants")
    page.wait_for_selector("#pool")
    assert "Students get a variant at their first visit." in page.inner_text("#pool-serving")
    assert_accessible(page, "the pool page while topped up")
    pool = wait_until(ready_with(prof, aid, K + MORE), f"{K + MORE} variants kept")
    new_kept = {v["id"] for v in pool["variants"] if v["state"] == "kept"} - first_kept
    assert pool["k"] == K + MORE and len(new_kept) == MORE, pool
    page.reload()
    page.screenshot(path=SHOTS / "variant_pool_topped_up.png", full_page=True)

    # A student who comes now gets one of the new variants (the least used); nobody else's lab changed.
    later = signed_in(browser, stack, tokens[names[K]])
    later.goto(f"{stack.url}/courses/{COURSE}")
    assert variant_of(stack, aid, names[K]) in new_kept
    later.close()
    for name in names[:K]:
        assert variant_of(stack, aid, name) == first[name], name
        student = signed_in(browser, stack, tokens[name])
        student.goto(f"{stack.url}/courses/{COURSE}")
        assert student.inner_text(f"#assignment-{aid}-lab-summary") == summaries[name], name
        student.close()
