"""Which runs each scoring rule reads, declared with the rule (rubric.scoring.RULE_READS): the declaration is enforced
where a rule reads a run (a read it does not declare is a rubric bug, like an undeclared tolerance; every L03 grade of
tests/rubric/test_scoring.py's golden sheets reads only what it declares), and it is what the service withholds with a
withheld item in every submission of the student (rubric.scoring.runs_read; issue 44, findings 5-A and 5-B)."""

from __future__ import annotations

import pytest

from rubric.l03 import LESSON
from rubric.one_factor import one_factor_findings
from rubric.rubrics import load_rubric
from rubric.scoring import LESSON_RUNS, RULE_READS, SCORING_RULES, runs_read
from rubric.scoring.scorer import Context, NotMeasured
from rubric.sheet import PredictionSheet
from tests.factories import reference_sheet

CHECKPOINT_RUNS = list(LESSON_RUNS)  # a checkpoint sheet submits no config: the lesson's runs alone
SHEET_RUNS = [*LESSON_RUNS, "sheet.table_exercise", "sheet.extension"]


def test_every_scoring_rule_declares_the_runs_it_reads():
    assert set(RULE_READS) == set(SCORING_RULES)
    assert all(item.check in RULE_READS for item in load_rubric("L03").items)


def test_a_rule_reading_a_run_it_does_not_declare_is_a_rubric_bug_not_a_grade():
    rubric = load_rubric("L03")
    sheet = PredictionSheet.model_validate(reference_sheet())
    ctx = Context(sheet, {}, rubric, one_factor_findings(sheet, rubric))
    ctx.item = next(i for i in rubric.items if i.check == "timing_n4")  # declares N4 alone
    with pytest.raises(KeyError, match=r"item C1 reads the run of 'N1' but its rule 'timing_n4' declares only"):
        ctx.result("N1")
    with pytest.raises(NotMeasured):  # a declared read goes on (and finds nothing measured here)
        ctx.result("N4")


@pytest.mark.parametrize(("item", "runs", "expected"), [
    # B3 reads the baseline and the table exercise: on a checkpoint sheet, the lesson's friction-table-0.30 is what
    # measures a table exercise (5-A); on a whole sheet, the student's own run as well
    ("B3", CHECKPOINT_RUNS, ["friction-baseline", "friction-table-0.30"]),
    ("B3", SHEET_RUNS, ["friction-baseline", "friction-table-0.30", "sheet.table_exercise"]),
    ("A2", SHEET_RUNS, ["N1", "N2", "N3", "N4"]),
    ("X2", SHEET_RUNS, ["N1", "sheet.extension"]),
    ("C5", CHECKPOINT_RUNS, ["friction-baseline"]),
    ("C2", SHEET_RUNS, []),  # conceptual: no run decides it
    ("A5", SHEET_RUNS, []),  # conceptual, although its evidence illustrates it with N1 and N2
    ("H6", SHEET_RUNS, sorted(SHEET_RUNS)),  # the engine version: every run's provenance
])
def test_the_runs_that_could_answer_an_item(item, runs, expected):
    assert runs_read(load_rubric("L03"), item, runs) == expected
    assert LESSON.runs_read(item, runs) == expected  # as the lesson declares it to the service
