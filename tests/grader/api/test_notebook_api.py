"""The notebook's doors on the API (issue 48): the sheet page's facts as data for the client (its questions and
fields, the page's draft, the standing), the form's Check with the page's verdict, the draft the page shows, and a
notebook uploaded as a submission, refused whole when bad."""

from __future__ import annotations

import pytest
from sqlalchemy import func, select

from grader.core.db import new_session
from grader.core.models import Course, Draft, Submission
from grader.core.rubrics import course_rubric
from grader.services.submissions import sheet_form as form_logic
from tests.factories import reference_sheet
from tests.notebooks import as_bytes, filled

pytestmark = pytest.mark.clock("2026-11-27T12:00:00Z")


@pytest.fixture
def aid(api):
    created = api.client.post("/v1/courses/l03/assignments", headers=api.as_("prof"), json={
        "title": "Week 3", "part": "sheet", "open_at": "2020-01-01T00:00:00Z", "due_at": "2099-01-01T00:00:00Z",
        "hard_close_at": "2099-01-02T00:00:00Z", "max_attempts": 2})
    assert created.status_code == 201, created.text
    return created.json()["id"]


def test_the_sheet_is_the_pages_facts_as_data(api, aid):
    listed = api.client.get("/v1/sheets", headers=api.as_("alice"))
    assert listed.status_code == 200, listed.text
    assert [(a["id"], a["title"], a["phase"], a["attempts_left"]) for a in listed.json()] == [(aid, "Week 3", "open", 2)]
    got = api.client.get(f"/v1/assignments/{aid}/sheet", headers=api.as_("alice"))
    assert got.status_code == 200, got.text
    sheet = got.json()
    assert sheet["standing"] | {"late_seconds": 0} == {"attempt": 1, "max_attempts": 2, "late_seconds": 0,
                                                       "late": "on time", "penalty": 0.0}
    a2 = next(i for i in sheet["items"] if i["id"] == "A2")
    assert a2["fields"][0] | {"choices": sorted(a2["fields"][0]["choices"])} == {
        "path": "answers.A2.direction", "words": "A2 direction", "widget": "radio",
        "choices": ["decrease", "increase", "unchanged"], "units": [], "required": True}
    assert [c["role"] for c in sheet["configs"]] == ["table_exercise", "extension"]
    assert sheet["draft"] == {"lesson": "L03", "student": "alice", "answers": {}}
    zh = api.client.get(f"/v1/assignments/{aid}/sheet", headers=api.as_("alice"), params={"language": "zh"}).json()
    assert next(i for i in zh["items"] if i["id"] == "A2")["question"] != a2["question"]
    assert api.client.get(f"/v1/assignments/{aid}/sheet", headers=api.as_("tess")).status_code == 404


def test_the_check_is_the_forms_and_the_draft_is_the_pages(api, aid):
    sheet = reference_sheet()
    sheet["configs"]["extension"]["duration"] = 2.0
    sheet["answers"]["A2"]["direction"] = "sideways"
    checked = api.client.post(f"/v1/assignments/{aid}/sheet/check", headers=api.as_("alice"), json={"sheet": sheet})
    assert checked.status_code == 200, checked.text
    body = checked.json()
    assert body["passes"] is False
    assert [(e["field"], e["words"]) for e in body["errors"]] == [("sheet.answers.A2.direction", "A2 direction")]
    extension = next(c for c in body["configs"] if c["role"] == "extension")
    assert extension["one_factor"] is False and extension["violations"] == ["duration"]
    with new_session() as session:  # the verdict is the form's own
        page, _ = form_logic.config_checks(session=session, sheet=sheet, part="sheet",
                                           book=course_rubric(session, session.scalar(select(Course.id)), "L03"))
    assert [(c.role, [v.field for v in c.violations], c.voids) for c in page] == \
        [(c["role"], c["violations"], c["voids"]) for c in body["configs"]]
    saved = api.client.put(f"/v1/assignments/{aid}/sheet/draft", headers=api.as_("alice"), json={"sheet": sheet})
    assert saved.status_code == 200, saved.text
    assert api.client.get(f"/v1/assignments/{aid}/sheet", headers=api.as_("alice")).json()["draft"] == sheet
    page = api.client.get(f"/assignments/{aid}/sheet", headers=api.as_("alice"))
    assert page.status_code == 200 and 'value="2.0"' in page.text  # the page's form shows the notebook's draft


def test_a_bad_notebook_is_refused_whole_and_a_good_one_submitted(api, aid):
    nb = filled(reference_sheet())
    nb["cells"].append(dict(next(c for c in nb["cells"] if "answer:A2" in c["metadata"].get("tags", [])),
                            id="again"))
    with new_session() as session:
        before = (session.scalar(select(func.count()).select_from(Submission)),
                  session.scalar(select(func.count()).select_from(Draft)))
    refused = api.client.post("/v1/notebooks", headers=api.as_("alice"), data={"assignment_id": aid},
                              files={"file": ("sheet.ipynb", as_bytes(nb), "application/x-ipynb+json")})
    assert refused.status_code == 422, refused.text
    assert "both hold answer:A2: keep one" in refused.json()["errors"][0]["rule"]
    with new_session() as session:
        assert (session.scalar(select(func.count()).select_from(Submission)),
                session.scalar(select(func.count()).select_from(Draft))) == before
    taken = api.client.post("/v1/notebooks", headers=api.as_("alice"), data={"assignment_id": aid},
                            files={"file": ("sheet.ipynb", as_bytes(filled(reference_sheet())), "application/json")})
    assert taken.status_code == 202, taken.text
    assert (taken.json()["assignment_id"], taken.json()["attempt"]) == (aid, 1)
    with new_session() as session:
        stored = session.get(Submission, taken.json()["id"])
        assert stored.sheet == reference_sheet() | {"student": "alice"}


def test_a_sign_in_link_gives_the_notebook_a_token_once(api, aid):
    issued = api.client.post("/v1/courses/l03/students/alice/sign-in-link", headers=api.as_("prof"))
    assert issued.status_code == 200, issued.text
    secret = issued.json()["sign_in_link"].rsplit("/sign-in/link/", 1)[1]
    used = api.client.post(f"/v1/sign-in-links/{secret}/token")
    assert used.status_code == 200, used.text
    assert (used.json()["user"], used.json()["course"], used.json()["expires_in_days"]) == ("alice", "l03", 7)
    mine = api.client.get("/v1/sheets", headers={"Authorization": f"Bearer {used.json()['token']}"})
    assert mine.status_code == 200 and [a["id"] for a in mine.json()] == [aid]
    again = api.client.post(f"/v1/sign-in-links/{secret}/token")
    assert again.status_code == 404 and "used" in again.json()["detail"], again.text
    assert api.client.post("/v1/sign-in-links/not-a-link/token").status_code == 404


def test_a_student_on_a_variant_gets_their_own_lab_words_and_check(api):
    """At an assignment with a variant pool (built as tests/grader/pages/test_variant_pages.py builds it), the
    client's sheet is the student's own lab (the course page's words, their numbers in the questions) and its Check
    compares their configs with their own baseline, as the form does."""
    import rubric
    from rubric.variants import texts
    from tests.grader.pages.test_variant_pages import drawn, pooled_assignment, variant_of, words

    aid = pooled_assignment(api)
    got = api.client.get(f"/v1/assignments/{aid}/sheet", headers=api.as_("alice"))
    assert got.status_code == 200, got.text
    mine = drawn()[variant_of(aid, "alice")]
    assert got.json()["lab"] == texts.parameter_summary(mine, "en")
    page = api.client.get(f"/assignments/{aid}/sheet", headers=api.as_("alice"))
    assert words(got.json()["lab"]) in page.text
    questions = {i["id"]: i["question"] for i in got.json()["items"]}
    assert questions["A1"] == texts.item_question(rubric.load_rubric("L03").item("A1"), mine, "en")
    sheet = reference_sheet()
    checked = api.client.post(f"/v1/assignments/{aid}/sheet/check", headers=api.as_("alice"), json={"sheet": sheet})
    assert checked.status_code == 200, checked.text
    with new_session() as session:
        own, _ = form_logic.config_checks(session=session, sheet=sheet, part="sheet", variant=mine,
                                          book=course_rubric(session, session.scalar(select(Course.id)), "L03"))
        shipped, _ = form_logic.config_checks(session=session, sheet=sheet, part="sheet",
                                              book=course_rubric(session, session.scalar(select(Course.id)), "L03"))
    assert [(c["role"], c["baseline"], c["violations"]) for c in checked.json()["configs"]] == \
        [(c.role, c.baseline, [v.field for v in c.violations]) for c in own]
    assert [c.violations for c in own] != [c.violations for c in shipped]  # the variant's baseline is not the lesson's
