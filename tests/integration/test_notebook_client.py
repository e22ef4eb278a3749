"""The notebook client (client/, `gradernb`, issue 48) in a real kernel: the template notebook, answered, is run top
to bottom by nbclient in an ipykernel against the real stack (API, Celery worker, Genesis). It signs in, lists the
assignments, checks a sheet whose extension breaks the one-factor rule (the page's verdict), fixes it, submits with the
confirmation's facts, follows the progress and shows the report inline; the grade equals the YAML sheet's, and the
draft it saved is the one the sheet page shows."""

from __future__ import annotations

import json
import os

import nbformat
import pytest
from nbclient import NotebookClient
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Draft, User
from tests.factories import ROOT, reference_sheet
from tests.integration.helpers import SHOTS, at
from tests.notebooks import filled

pytestmark = [pytest.mark.integration, pytest.mark.slow]

# Cells run between the template's check and its submit: the first check must show the violation, then the fix.
BETWEEN = [
    'assert not first.passes, first\n'
    'assert [c["role"] for c in first.violations] == ["extension"], first\n'
    'assert first.violations[0]["violations"] == ["duration"], first\n'
    'first',
    'sheet.config("extension", duration=1.5)  # back to N1\'s: only dt and substeps differ now\n'
    'second = sheet.check()\n'
    'assert second.passes, second\n'
    'second',
]


def outputs(nb, kind: str) -> str:
    return "\n".join(str(o.get("data", {}).get(kind, "")) + str(o.get("text", "")) for cell in nb.cells
                     if cell.cell_type == "code" for o in cell.get("outputs", []))


def test_a_notebook_run_in_a_real_kernel_checks_fixes_submits_and_shows_the_report(stack, graded, tmp_path):
    prof = stack.client("prof")
    assignment = prof.create_assignment("l03-test", {
        "title": "Notebook week", "part": "sheet", "open_at": at(days=-1), "due_at": at(days=2),
        "hard_close_at": at(days=3), "max_attempts": 3})
    sheet = reference_sheet()
    sheet["configs"]["extension"]["duration"] = 2.0  # a second factor: the one-factor rule voids the extension
    nb = nbformat.reads(json.dumps(filled(sheet)), as_version=4)  # each source one string, as Jupyter reads it
    code = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    check_cell = next(i for i in code if "sheet.check()" in nb.cells[i].source)
    nb.cells[check_cell].source = nb.cells[check_cell].source.replace("sheet.check()", "first = sheet.check()\nfirst")
    nb.cells[check_cell + 1:check_cell + 1] = [nbformat.v4.new_code_cell(s) for s in BETWEEN]
    submit_cell = next(c for c in nb.cells if "sheet.submit()" in c.source)
    submit_cell.source = submit_cell.source.replace("sheet.submit()", "sheet.submit(poll_s=0.5, timeout_s=900)") \
        + "\nreport = submission.report()\nprint(json.dumps({'submission': submission.id, 'total': report.total, "\
          "'check': report.check_line}))\nreport"
    submit_cell.source = "import json\n" + submit_cell.source
    env = dict(os.environ, GRADER_URL=stack.url, GRADER_TOKEN=stack.tokens["alice"],
               GRADER_ASSIGNMENT=str(assignment["id"]),
               PYTHONPATH=os.pathsep.join([str(ROOT / "client"), os.environ.get("PYTHONPATH", "")]))
    NotebookClient(nb, timeout=1200, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
                   ).execute(env=env)
    SHOTS.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, SHOTS / "notebook_client.ipynb")  # docs/student.md's screenshot is drawn from it

    html, text = outputs(nb, "text/html"), outputs(nb, "text/plain")
    assert "Your assignments" in html and "Notebook week" in html
    assert "one-factor violation" in html and "Check: nothing to fix" in html  # the first check, then the second
    assert "submitting attempt 1 of 3, on time, no late penalty" in html
    assert "<progress" in html
    done = json.loads(next(line for line in text.splitlines() if line.startswith('{"submission"')))
    assert done["check"] == "L03 CHECK: PASSED"
    assert "L03 CHECK: PASSED" in html and "<svg" in html and f"/submissions/{done['submission']}" in html

    alice = stack.client("alice")
    grade = alice.grade(done["submission"])
    yaml_grade = alice.grade(graded["alice"]["id"])
    assert (grade["total"], grade["max_total"]) == (yaml_grade["total"], yaml_grade["max_total"]) == (done["total"],
                                                                                                      grade["max_total"])
    assert [(i["id"], i["verdict"], i["score"]) for i in grade["items"]] == \
        [(i["id"], i["verdict"], i["score"]) for i in yaml_grade["items"]]
    with Session(stack.engine) as session:  # the draft the notebook saved is the sheet page's draft
        user = session.scalar(select(User).where(User.name == "alice"))
        draft = session.scalar(select(Draft).where(Draft.user_id == user.id,
                                                   Draft.assignment_id == assignment["id"]))
        fixed = reference_sheet()
        assert draft.sheet["answers"] == fixed["answers"]
        assert draft.sheet["configs"]["extension"] == fixed["configs"]["extension"] | {"duration": 1.5}
