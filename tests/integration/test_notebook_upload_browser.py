"""A notebook uploaded as a submission (issue 48), over the real stack (API, Celery worker, Genesis, PostgreSQL,
Redis) and in a real browser: the template notebook filled with the reference answers is graded exactly as the YAML
reference sheet, through the API and through the sheet page's upload and confirmation; every bad notebook is refused
with its reason, and no submission or draft is stored for it."""

from __future__ import annotations

import json

import httpx
import pytest
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.core.models import Draft, Submission
from tests.factories import reference_sheet
from tests.integration.helpers import SHOTS, WAIT_LIMIT_S, signed_in
from tests.notebooks import as_bytes, filled

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def items_of(client, submission_id: int) -> tuple[float, float, list[tuple]]:
    grade = client.grade(submission_id)
    return grade["total"], grade["max_total"], [(i["id"], i["verdict"], i["score"]) for i in grade["items"]]


def post_notebook(stack, who: str, data: bytes, **form) -> httpx.Response:
    return httpx.post(f"{stack.url}/v1/notebooks", headers={"Authorization": f"Bearer {stack.tokens[who]}"},
                      files={"file": ("sheet.ipynb", data, "application/x-ipynb+json")}, data=form, timeout=60)


def stored(stack) -> tuple[int, list]:
    with Session(stack.engine) as session:
        return (session.scalar(select(func.count()).select_from(Submission)),
                sorted((d.user_id, d.assignment_id, json.dumps(d.sheet, sort_keys=True))
                       for d in session.scalars(select(Draft))))


def bad_notebooks() -> dict[str, tuple[bytes, str]]:
    """Each kind of notebook the service refuses, with words its refusal must hold."""
    template = filled(reference_sheet())
    nbformat3 = {"nbformat": 3, "nbformat_minor": 0, "metadata": {}, "worksheets": [{"cells": []}]}
    untagged = json.loads(json.dumps(template))
    for cell in untagged["cells"]:
        cell["metadata"].pop("tags", None)
    twice = json.loads(json.dumps(template))
    a2 = next(c for c in twice["cells"] if "answer:A2" in c["metadata"].get("tags", []))
    twice["cells"].append(dict(a2, id="another-a2"))
    outputs = json.loads(json.dumps(template))
    next(c for c in outputs["cells"] if c["cell_type"] == "code")["outputs"] = [
        {"output_type": "stream", "name": "stdout", "text": "x" * 300_000}]
    return {
        "not JSON": (b'{"cells": [', "not a notebook: not JSON"),
        "nbformat 3": (json.dumps(nbformat3).encode(), "only version 4 notebooks are read"),
        "no answer cell": (as_bytes(untagged), "no answer cell"),
        "two cells for A2": (as_bytes(twice), "both hold answer:A2"),
        "huge outputs": (as_bytes(outputs), "clear them"),
    }


def test_the_filled_template_uploaded_to_the_api_grades_as_the_yaml_sheet(stack, graded):
    alice = stack.client("alice")
    response = post_notebook(stack, "alice", as_bytes(filled(reference_sheet())))
    assert response.status_code == 202, response.text
    final = alice.wait(response.json()["id"], poll_s=0.5, timeout_s=WAIT_LIMIT_S)
    assert final["status"] == "graded", final
    yaml_grade = items_of(alice, graded["alice"]["id"])
    assert items_of(alice, final["id"]) == yaml_grade
    assert yaml_grade[0] == yaml_grade[1]  # the reference answers earn every point: the comparison is not vacuous


@pytest.mark.parametrize("kind", sorted(bad_notebooks()))
def test_each_bad_notebook_is_refused_by_the_api_with_its_reason_and_stores_nothing(stack, kind):
    data, words = bad_notebooks()[kind]
    before = stored(stack)
    response = post_notebook(stack, "alice", data)
    assert response.status_code == 422, response.text
    body = response.json()
    assert body["detail"] == "invalid notebook" and words in body["errors"][0]["rule"], body
    assert stored(stack) == before


def test_a_50_mb_file_is_refused_before_it_is_read(stack):
    before = stored(stack)
    response = post_notebook(stack, "alice", b" " * (50 * 1024 * 1024))
    assert response.status_code == 413, response.text
    assert "bytes" in response.text
    assert stored(stack) == before


def test_a_sheet_error_in_a_notebook_names_its_cell(stack):
    sheet = reference_sheet()
    sheet["answers"]["A2"]["direction"] = "sideways"
    response = post_notebook(stack, "alice", as_bytes(filled(sheet)))
    assert response.status_code == 422, response.text
    errors = response.json()["errors"]
    a2 = [e for e in errors if e["field"].startswith("sheet.answers.A2")]
    assert a2 and a2[0]["rule"].startswith("cell ") and "(answer:A2)" in a2[0]["rule"], errors


def test_the_filled_template_uploaded_on_the_sheet_page_grades_as_the_yaml_sheet(browser, stack, graded, tmp_path):
    page = signed_in(browser, stack, "alice")
    page.goto(f"{stack.url}/sheet")
    bad = tmp_path / "bad.ipynb"
    bad.write_bytes(bad_notebooks()["two cells for A2"][0])
    before = stored(stack)
    page.set_input_files("#notebook-file", str(bad))
    page.click("#notebook button[type=submit]")
    page.wait_for_selector("#check-summary")
    assert "both hold answer:A2: keep one" in page.inner_text("#check-summary")
    assert stored(stack) == before  # the draft as it was, no submission
    page.screenshot(path=SHOTS / "notebook_refused.png", full_page=False)

    notebook = tmp_path / "sheet.ipynb"
    notebook.write_bytes(as_bytes(filled(reference_sheet())))
    page.set_input_files("#notebook-file", str(notebook))
    page.click("#notebook button[type=submit]")
    page.wait_for_selector("#confirm")
    assert "Your notebook's answers are now your draft" in page.inner_text("#notice")
    page.click("#confirm-submit")
    page.wait_for_url(f"{stack.url}/submissions/*/progress")
    submission = int(page.url.split("/")[-2])
    alice = stack.client("alice")
    final = alice.wait(submission, poll_s=0.5, timeout_s=WAIT_LIMIT_S)
    assert final["status"] == "graded", final
    assert items_of(alice, submission) == items_of(alice, graded["alice"]["id"])
