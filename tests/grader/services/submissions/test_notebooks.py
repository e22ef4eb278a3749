"""Reading a notebook as a sheet (grader.services.submissions.notebooks): the template filled with the reference
answers reads as the reference sheet; every bad notebook is refused with its reason, naming the cell; nothing runs."""

from __future__ import annotations

import copy
import json

import pytest

from grader.services.errors import Invalid
from grader.services.submissions import notebooks
from tests.factories import reference_sheet
from tests.notebooks import TEMPLATE, as_bytes, filled, validated


def refusal(data: bytes) -> list[dict]:
    with pytest.raises(Invalid) as refused:
        notebooks.read(data)
    assert refused.value.detail == "invalid notebook"
    return refused.value.errors


def test_the_filled_template_reads_as_the_sheet_it_answers():
    sheet = reference_sheet()
    found = notebooks.read(as_bytes(validated(filled(sheet))))
    assert found.lesson == "L03"
    assert found.answers == sheet["answers"]
    assert found.configs == sheet["configs"]
    assert found.sheet(student="reference", lesson=None) == sheet
    assert found.cells["answer", "A2"].number > 1


def test_the_blank_template_reads_with_its_nones():
    found = notebooks.read(TEMPLATE.read_bytes())
    assert found.answers["A2"] == {"direction": None}
    assert set(found.answers) == set(reference_sheet()["answers"])
    assert set(found.configs) == {"table_exercise", "extension"}


def test_a_cell_is_parsed_never_run(tmp_path):
    marker = tmp_path / "ran"
    nb = filled(reference_sheet())
    cell = next(c for c in nb["cells"] if "answer:A2" in c["metadata"].get("tags", []))
    cell["source"] = f"A2 = open({str(marker)!r}, 'w').write('x')"
    errors = refusal(as_bytes(nb))
    assert not marker.exists()
    assert "only literal values" in errors[0]["rule"] and "(answer:A2)" in errors[0]["rule"]
    assert errors[0]["field"].startswith("notebook.cells.")


@pytest.mark.parametrize("data, field, words", [
    (b"{not json", "notebook", "not JSON (line 1, column 2"),
    (b"\xff\xfe", "notebook", "UTF-8"),
    (b"[1, 2]", "notebook", "a JSON object with nbformat and cells"),
    (json.dumps({"nbformat": 3, "nbformat_minor": 0, "metadata": {}, "worksheets": []}).encode(),
     "notebook.nbformat", "nbformat 3: only version 4"),
    (json.dumps({"nbformat": 4, "nbformat_minor": 5, "metadata": {}, "cells": [{"cell_type": "code"}]}).encode(),
     "notebook", "not a valid nbformat 4 notebook"),
    (b" " * (notebooks.MAX_BYTES + 1), "notebook", f"at most {notebooks.MAX_BYTES} bytes"),
])
def test_a_file_that_is_no_notebook_is_refused_with_its_reason(data, field, words):
    errors = refusal(data)
    assert errors[0]["field"] == field and words in errors[0]["rule"], errors


def test_no_answer_cell_is_refused():
    nb = json.loads(TEMPLATE.read_text())
    for cell in nb["cells"]:
        cell["metadata"].pop("tags", None)
    errors = refusal(as_bytes(nb))
    assert errors == [{"field": "notebook.cells", "rule": errors[0]["rule"]}]
    assert errors[0]["rule"].startswith("no answer cell: tag each answer's code cell answer:ID")


def test_two_cells_for_one_item_are_refused_naming_both():
    nb = filled(reference_sheet())
    first = next(i for i, c in enumerate(nb["cells"]) if "answer:A2" in c["metadata"].get("tags", []))
    nb["cells"].append(copy.deepcopy(nb["cells"][first]) | {"id": "second-a2"})
    errors = refusal(as_bytes(nb))
    assert errors[0]["rule"] == f"cells {first + 1} and {len(nb['cells'])} both hold answer:A2: keep one"


def test_metadata_marks_a_cell_as_tags_do():
    nb = filled(reference_sheet())
    cell = next(c for c in nb["cells"] if "answer:A2" in c["metadata"].get("tags", []))
    cell["metadata"] = {"grader": {"answer": "A2"}}
    assert notebooks.read(as_bytes(validated(nb))).answers["A2"] == reference_sheet()["answers"]["A2"]
    cell["metadata"]["tags"] = ["answer:A2", "answer:A3"]
    assert "marked 2 times" in refusal(as_bytes(nb))[0]["rule"]


def test_huge_outputs_are_refused():
    nb = filled(reference_sheet())
    cell = next(c for c in nb["cells"] if c["cell_type"] == "code")
    cell["outputs"] = [{"output_type": "stream", "name": "stdout", "text": "x" * (notebooks.MAX_OUTPUT_BYTES + 1)}]
    errors = refusal(as_bytes(validated(nb)))
    assert errors[0]["field"] == "notebook.outputs" and "clear them" in errors[0]["rule"]


@pytest.mark.parametrize("source, words", [
    ("A2 = {'direction': 'decrease'", "not Python"),
    ("B2 = {'lane': 'low'}", "assigns B2, but its tag says A2"),
    ("A2 = {'direction': 'decrease'}\nprint(A2)", "one assignment"),
    ("A2 = {'direction': direction}", "only literal values"),
])
def test_an_answer_cell_that_is_not_one_literal_is_refused_naming_it(source, words):
    nb = filled(reference_sheet())
    number, cell = next((n, c) for n, c in enumerate(nb["cells"], 1) if "answer:A2" in c["metadata"].get("tags", []))
    cell["source"] = source
    errors = refusal(as_bytes(nb))
    assert errors[0]["field"] == f"notebook.cells.{number}"
    assert errors[0]["rule"].startswith(f"cell {number} (answer:A2)") and words in errors[0]["rule"], errors


def test_a_tagged_markdown_cell_is_refused():
    nb = filled(reference_sheet())
    cell = next(c for c in nb["cells"] if "answer:A2" in c["metadata"].get("tags", []))
    cell.update(cell_type="markdown")
    cell.pop("outputs"), cell.pop("execution_count")
    assert "is a markdown cell: an answer cell is a code cell" in refusal(as_bytes(nb))[0]["rule"]


def test_a_sheet_error_names_the_cell_it_comes_from():
    found = notebooks.read(as_bytes(filled(reference_sheet())))
    error = notebooks.with_cells(Invalid("invalid sheet", [
        {"field": "sheet.answers.A2.direction", "rule": "Input should be 'decrease', 'increase' or 'unchanged'"},
        {"field": "assignment_id", "rule": "closed"}]), found)
    number = found.cells["answer", "A2"].number
    assert error.errors == [
        {"field": "sheet.answers.A2.direction",
         "rule": f"cell {number} (answer:A2): Input should be 'decrease', 'increase' or 'unchanged'"},
        {"field": "assignment_id", "rule": "closed"}]


@pytest.mark.parametrize("source", ["A2 = {'direction': 'de\x00crease'}", "A2 = " + "[" * 300 + "]" * 300])
def test_a_cell_the_parser_cannot_take_is_refused_naming_it(source):
    nb = filled(reference_sheet())
    cell = next(c for c in nb["cells"] if "answer:A2" in c["metadata"].get("tags", []))
    cell["source"] = source
    errors = refusal(as_bytes(nb))
    assert "(answer:A2)" in errors[0]["rule"] and errors[0]["field"].startswith("notebook.cells."), errors
