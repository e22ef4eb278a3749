"""The lesson interface (rubric.lesson, issue 45): L03 is found by its entry point, and what it declares is what the
service grades with today."""

from __future__ import annotations

import pytest

from rubric import CHECK_CASES, BASELINE_CASES, cases_to_run, grade_sheet
from rubric.check import evaluate, verdict_line
from rubric.lesson import Lesson, LessonNotFound, lesson, lesson_names
from rubric.lesson_check import check_lesson
from rubric.rubrics import LESSONS_DIR, rubric_versions
from rubric.scoring import SCORING_RULES


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
    with pytest.raises(LessonNotFound, match=r"no lesson 'L02' is installed \(entry points l03_grader.lessons: .*L03"):
        lesson("L02")
