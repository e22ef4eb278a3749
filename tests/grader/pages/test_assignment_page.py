"""The instructor's assignment page and the dashboard's counted grades, on the in-process app (SQLite)."""

from __future__ import annotations

import pytest

from tests.grader.services.setup.test_assignments import at, checkpoint_sheet, create, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured


@pytest.fixture
def graded_class(api):
    """A late-penalized assignment: alice twice (the second worse), bob once with an extension, carol never."""
    api.client.post("/v1/courses/l03/roster", headers=api.as_("prof"),
                    json={"csv": "student_id,name,email\ncarol,Carol Shaw,carol@example.edu\n"})
    aid = create(api, title="Checkpoints week 3", open_at=at(-2), due_at=at(hours=-26), hard_close_at=at(1), late_penalty_per_day=0.1,
                 counted_attempt="best", item_visibility={"C3": "on_release"}).json()["id"]
    api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"),
                    json={"student": "bob", "due_at": at(1), "hard_close_at": at(2)})
    first = submit(api, aid).json()
    worse = checkpoint_sheet()
    worse["answers"]["C2"]["reason"] = "it_is_valid"
    second = submit(api, aid, sheet=worse).json()
    bob = submit(api, aid, who="bob").json()
    return aid, first, second, bob


def test_the_page_shows_settings_students_attempts_lateness_and_counted_grades(api, graded_class):
    aid, first, second, bob = graded_class
    page = api.client.get(f"/assignments/{aid}", headers=api.as_("prof"))
    assert page.status_code == 200, page.text
    text = page.text
    assert "Checkpoints week 3" in text and "10% per started day" in text and "the best counts" in text
    assert "not released yet" in text and "on release <span class=\"muted\">(own setting)" in text
    # alice: two attempts, both a day and some hours late (2 days charged), the first counts: 8 less 20% is 6.4.
    assert f'id="attempt-{first["id"]}" class="counts"' in text and f'id="attempt-{second["id"]}">' in text
    assert "1 d 2 h late (2 days charged)" in text and "<strong>6.4</strong>" in text and "−20%" in text
    # bob: his extension, who granted it, on time; carol: on the roster, no attempt.
    assert "<strong>extension</strong>" in text and "granted by prof" in text and "on time" in text
    assert 'id="student-carol"' in text and "Carol Shaw" in text and "no attempt yet" in text
    csv = api.client.get(f"/assignments/{aid}/grades.csv", headers=api.as_("prof"))
    assert csv.status_code == 200 and csv.text.splitlines()[1].startswith("alice,6.4,8,8,0.2,")


@pytest.mark.parametrize("who", ["alice", "tess", "eve"])
def test_only_the_courses_instructors_see_the_page(api, graded_class, who):
    aid = graded_class[0]
    for path in (f"/assignments/{aid}", f"/assignments/{aid}/grades.csv"):
        response = api.client.get(path, headers=api.as_(who))
        assert response.status_code == 404 and "Checkpoints week 3" not in response.text
    assert api.client.get("/assignments/99999999999", headers=api.as_("prof")).status_code == 404


def test_the_dashboard_shows_each_assignments_counted_grades_and_links_its_page(api, graded_class):
    aid = graded_class[0]
    data = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
    (assignment,) = data["assignments"]
    assert assignment["page"] == f"/assignments/{aid}"
    assert [(g["student"], g["counted_score"], g["raw_score"], g["penalty"]) for g in assignment["grades"]] == [
        ("alice", 6.4, 8, 0.2), ("bob", 8, 8, 0)]
    page = api.client.get("/courses/l03/dashboard", headers=api.as_("prof")).text
    assert f'<a href="/assignments/{aid}">#{aid} Checkpoints week 3</a>' in page
    assert f'id="assignment-{aid}-grades"' in page and "6.4 / 8" in page
