"""The lesson interface (rubric.lesson, issue 45): L03 is found by its entry point, and what it declares is what the
service grades with today."""

from __future__ import annotations

import pytest

from rubric import CHECK_CASES, BASELINE_CASES
from rubric.check import evaluate, verdict_line
from rubric.lesson import Lesson, LessonNotFound, lesson, lesson_names
from rubric.lesson_check import check_lesson
from rubric.rubrics import LESSONS_DIR, rubric_versions
from rubric.scoring import SCORING_RULES, cases_to_run, grade_sheet


def test_l03_is_installed_by_entry_point_and_declares_what_the_service_grades_with():
    assert "L03" in lesson_names()
    l03 = lesson("L03")
    assert isinstance(l03, Lesson) and l03.origin == "entry point L03 = rubric.l03:LESSON"
    assert (l03.grade_sheet, l03.cases_to_run, l03.evaluate_check, l03.verdict_line) == (
        grade_sheet, cases_to_run, evaluate, verdict_line)
    assert l03.cases is BASELINE_CASES and tuple(l03.check_cases) == tuple(CHECK_CASES) and l03.scoring_rules is SCORING_RULES
    assert list(l03.rubric_files()) == rubric_versions("L03") and l03.files == LESSONS_DIR
    assert l03.verdict_line(True) == "L03 CHECK: PASSED" and l03.title("zh") != l03.title("en")
    assert check_lesson(l03) == []


def test_an_unknown_lesson_names_the_installed_ones():
    with pytest.raises(LessonNotFound, match=r"no lesson 'L04' is installed \(entry points l03_grader.lessons: L02, L03"):
        lesson("L04")


def test_a_lessons_reviewed_files_are_read_from_the_folder_its_declaration_names(monkeypatch, tmp_path):
    """rubric.rubrics.lesson_folder: the rubric versions, audit tolerances, variant spaces and texts of a lesson are
    where its declaration says (an installed lesson's own package), not in a folder the service names."""
    import dataclasses
    import shutil

    from rubric import lesson as registry
    from rubric import load_rubric
    from rubric.discrepancy import audit_versions
    from rubric.rubrics import lesson_folder
    from rubric.variants import variant_space_versions

    assert lesson_folder("L03") == lesson("L03").files and lesson_folder("L99") is None
    assert rubric_versions("L99") == [] and audit_versions("L99") == []
    moved = tmp_path / "l03-files"
    shutil.copytree(LESSONS_DIR, moved)
    (moved / "L03-v1.yaml").unlink()
    (moved / "L03-audit-v2.yaml").write_text((moved / "L03-audit-v1.yaml").read_text().replace('version: "1"',
                                                                                             'version: "2"'))
    monkeypatch.setattr(registry, "lesson", lambda name: dataclasses.replace(lesson(name), files=moved))
    assert rubric_versions("L03") == ["2"] and audit_versions("L03") == ["1", "2"]
    assert variant_space_versions("L03") == ["1", "2"] and load_rubric("L03").version == "2"
