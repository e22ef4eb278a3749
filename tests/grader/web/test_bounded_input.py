"""Bounded work and no 500 from bad input (issue 31, items 3 and 4): every sheet is held to its caps before any work
(a config of thousands of keys, a key with a dot colliding with another's path), each step that runs per key is
linear, a file part where a text is expected, a roster with a field past the csv module's limit or CR-only line
endings, each answered 4xx naming the field or line; and a 500 that does happen carries the security headers."""

from __future__ import annotations

import pytest
import yaml
from fastapi.testclient import TestClient

from grader.core.db import new_session
from grader.core.models import Draft, User
from grader.services.submissions import sheet_form
from tests.factories import REFERENCE_YAML, reference_sheet
from tests.grader.pages.test_sheet_form import form_fields, import_yaml
from tests.grader.pages.test_submit_confirm import confirm_fields


def _with_config(**extra) -> dict:
    sheet = reference_sheet()
    sheet["configs"]["table_exercise"] |= extra
    return sheet


def _store_draft(sheet: dict, who: str = "alice") -> None:
    """A draft as an earlier version stored it, without today's checks (the form and the import refuse it now)."""
    with new_session() as session:
        user = session.query(User).filter_by(name=who).one()
        session.add(Draft(user_id=user.id, assignment_id=None, sheet=sheet))
        session.commit()


COLLIDING = _with_config(a=1, **{"a.b": 2})


def test_a_yaml_whose_keys_collide_is_refused_naming_the_key(api):
    refused = import_yaml(api, yaml.safe_dump(COLLIDING))
    assert refused.status_code == 422, refused.text[:2000]
    assert '<a href="#config-table_exercise">table exercise <code>a.b</code></a>: a key is 1 to 64 characters of ' \
           'text without a dot' in refused.text
    assert 'name="configs.table_exercise.a"' not in api.client.get("/sheet", headers=api.as_("alice")).text


@pytest.mark.parametrize("action", ["save", "check", "export", "submit"])
def test_a_stored_draft_whose_keys_collide_answers_4xx_naming_the_key_for_every_action(api, action):
    _store_draft(COLLIDING)
    page = api.client.get("/sheet", headers=api.as_("alice"))
    assert page.status_code == 200, page.text[:2000]
    answered = api.client.post("/sheet", headers=api.as_("alice"), data={**form_fields(page.text), "action": action})
    assert answered.status_code == 422, answered.text[:2000]
    assert "<code>a.b</code>" in answered.text and "without a dot" in answered.text
    autosaved = api.client.post("/sheet/draft", headers=api.as_("alice"), data=form_fields(page.text))
    assert autosaved.status_code == 422 and "sheet.configs.table_exercise.a.b" in autosaved.text
    # A corrected YAML replaces it, and the form works again.
    assert import_yaml(api, REFERENCE_YAML.read_text()).status_code == 200


def test_a_confirmed_submission_of_a_colliding_draft_is_refused_naming_the_key(api):
    page = import_yaml(api, REFERENCE_YAML.read_text())
    shown = api.client.post("/sheet", headers=api.as_("alice"), data={**form_fields(page.text), "action": "submit"})
    with new_session() as session:  # the draft changed under the confirmation, as an old version could store it
        draft = session.query(Draft).one()
        draft.sheet = COLLIDING
        session.commit()
    fields = confirm_fields(shown.text)
    from grader.pages.submissions.sheet_form import sheet_digest

    fields["digest"] = sheet_digest(COLLIDING)
    refused = api.client.post("/sheet", headers=api.as_("alice"), data=fields, follow_redirects=False)
    assert refused.status_code == 422 and "<code>a.b</code>" in refused.text, refused.text[:2000]


def test_thousands_of_extra_config_keys_are_refused_before_any_work(api):
    many = _with_config(**{f"k{i}": i for i in range(8000)})
    refused = import_yaml(api, yaml.safe_dump(many))
    assert refused.status_code == 422, refused.text[:2000]
    assert 'table exercise</a>: at most 64 keys (this one has 8003)' in refused.text
    api_refused = api.client.post("/v1/submissions", json={"sheet": many}, headers=api.as_("alice"))
    assert api_refused.status_code == 422
    assert api_refused.json()["errors"] == [{"field": "sheet.configs.table_exercise",
                                             "rule": "at most 64 keys (this one has 8003)"}]
    # A draft stored that large by an earlier version: the form's check refuses it by its size, not after the work.
    _store_draft(_with_config(**{f"k{i}": i for i in range(2000)}))
    assert api.client.get("/sheet", headers=api.as_("alice")).status_code == 200
    checked = api.client.post("/sheet", headers=api.as_("alice"), data={"student": "alice", "action": "check"})
    assert checked.status_code == 422 and "at most 64 keys (this one has 2003)" in checked.text


def test_a_stored_draft_past_the_caps_is_never_rendered_input_by_input(api):
    """The form shows the refusal and a fresh form, not 8,000 inputs (each one more step of the render)."""
    _store_draft(_with_config(**{f"k{i}": i for i in range(8000)}))
    page = api.client.get("/sheet", headers=api.as_("alice"))
    assert page.status_code == 200, page.text[:2000]
    assert 'id="check-summary"' in page.text and "at most 64 keys (this one has 8003)" in page.text
    assert 'name="configs.table_exercise.k0"' not in page.text and page.text.count("<input") < 400


@pytest.mark.parametrize("sheet, field, rule", [
    (_with_config(lanes=[{"name": "l"}] * 17), "sheet.configs.table_exercise.lanes", "at most 16 items"),
    ({**reference_sheet(), "student": "x" * 4001}, "sheet.student", "at most 4000 characters"),
    ({**reference_sheet(), "deep": [[[[[[[[[[[1]]]]]]]]]]]}, "sheet.deep.0.0.0.0.0.0.0.0.0", "nested at most 10"),
    ({**reference_sheet(), "x" * 65: 1}, "sheet." + "x" * 64, "a key is 1 to 64 characters"),
    ({**reference_sheet(), "e": {f"k{i}": [1] * 15 for i in range(40)}}, "sheet", "at most 500 values in all"),
])
def test_each_cap_is_named_with_its_path(api, sheet, field, rule):
    refused = api.client.post("/v1/submissions", json={"sheet": sheet}, headers=api.as_("alice"))
    assert refused.status_code == 422, refused.text
    assert any(e["field"] == field and rule in e["rule"] for e in refused.json()["errors"]), refused.json()


class _CountedNames(list):
    """The inputs' names, counting how often anything walks through them."""

    walked = 0

    def __iter__(self):
        type(self).walked += 1
        return super().__iter__()


def test_placing_errors_beside_inputs_walks_the_inputs_once_not_once_per_error():
    names = _CountedNames([f"configs.table_exercise.k{i}" for i in range(500)] + ["configs.table_exercise"])
    errors = [{"field": f"sheet.configs.table_exercise.k{i}.x", "rule": "r"} for i in range(500)]
    errors.append({"field": "sheet.answers.A1", "rule": "unplaced"})
    _CountedNames.walked = 0
    placed, unplaced = sheet_form.by_input(errors, names)
    assert _CountedNames.walked <= 1
    assert placed["configs.table_exercise.k7"] == ["r"] and unplaced == [errors[-1]]
    # The longest input name its field starts with, dot by dot (not a name that merely shares its first letters).
    placed, _ = sheet_form.by_input([{"field": "sheet.configs.table_exercise.k10.y", "rule": "r"}],
                                    ["configs.table_exercise", "configs.table_exercise.k1"])
    assert placed == {"configs.table_exercise": ["r"]}


def test_a_file_part_where_the_form_has_a_text_input_is_a_422_naming_the_field(api):
    fields = form_fields(api.client.get("/sheet", headers=api.as_("alice")).text)
    fields.pop("student")
    for path in ("/sheet", "/sheet/draft"):
        refused = api.client.post(path, headers=api.as_("alice"), data={**fields, "action": "check"},
                                  files={"student": ("student.txt", b"alice", "text/plain")})
        assert refused.status_code == 422, refused.text[:2000]
        assert "<code>student</code>: must be text, not a file" in refused.text


HUGE_FIELD = "student_id,name,email\ns1001," + "x" * 140_000 + ",ada@example.edu\n"
CR_ONLY = "student_id,name,email\rs1001,Ada Lovelace,ada@example.edu\rs1002,Alan Turing,alan@example.edu\r"


def test_a_roster_with_a_field_past_the_csv_limit_is_a_422_naming_the_line(api):
    refused = api.client.post("/v1/courses/l03/roster", json={"csv": HUGE_FIELD[:199_000]}, headers=api.as_("prof"))
    assert refused.status_code == 422, refused.text[:2000]
    assert refused.json()["errors"][0]["field"].startswith("csv.line 2"), refused.json()
    page = api.client.post("/courses/l03/setup/roster", headers=api.as_("prof"),
                           files={"csv": ("r.csv", HUGE_FIELD.encode(), "text/csv")})
    assert page.status_code == 422 and "csv.line 2" in page.text, page.text[:2000]


def test_a_roster_with_cr_only_line_endings_is_read_line_by_line(api):
    imported = api.client.post("/v1/courses/l03/roster", json={"csv": CR_ONLY}, headers=api.as_("prof"))
    assert imported.status_code == 200, imported.text
    assert [e["student"] for e in imported.json()] == ["s1001", "s1002"]
    bad = CR_ONLY.replace("alan@example.edu", "not-an-email")
    refused = api.client.post("/courses/l03/setup/roster", headers=api.as_("prof"),
                              files={"csv": ("r.csv", bad.encode(), "text/csv")})
    assert refused.status_code == 422 and "csv.line 3.email" in refused.text, refused.text[:2000]


def test_only_the_courses_instructor_imports_a_roster_even_past_the_route():
    """The service checks the role itself (issue 31, item 8): a loosened route dependency lets nobody else in."""
    from grader.services.setup import roster
    from grader.services.errors import Forbidden, NotFound

    class Person:
        def __init__(self, role, course_id):
            self.role, self.course_id, self.name = role, course_id, "someone"

    class Course:
        id, name = 1, "l03"

    for who, error in ((Person("auditor", 1), Forbidden), (Person("student", 1), Forbidden),
                       (Person("instructor", 2), NotFound)):
        with pytest.raises(error):
            roster.import_csv(session=None, course=Course(), text="student_id,name,email\n", by=who)


def test_a_500_carries_the_security_headers(api, monkeypatch):
    from grader.services.submissions import submit as submissions

    def broken(**_):
        raise RuntimeError("a bug")

    monkeypatch.setattr(submissions, "visible_submissions", broken)
    from grader.main import app

    client = TestClient(app, raise_server_exceptions=False)
    for path in ("/v1/submissions", "/submissions"):
        answer = client.get(path, headers=api.as_("alice"))
        assert answer.status_code == 500, (path, answer.text)
        assert answer.headers["X-Content-Type-Options"] == "nosniff" and answer.headers["X-Frame-Options"] == "DENY"
        assert "default-src 'self'" in answer.headers["Content-Security-Policy"]
        assert answer.headers["Cache-Control"] == "private, no-store"
        assert "a bug" not in answer.text
