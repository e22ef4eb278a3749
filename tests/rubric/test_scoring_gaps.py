"""Part B's scoring rules where the suite never looked (issue 37, item 3): a B1 answer naming some of the changed lanes
or none, and a B2 whose baseline has a lane that never stops. Graded on the session's real measurements
(`measured`), changed only where a test says what another engine or run would have recorded."""

from __future__ import annotations

import dataclasses

import pytest

from rubric import grade_sheet, parse_sheet
from rubric.metrics import Stop
from tests.factories import reference_sheet, sheet_results

BASELINE = "friction-baseline"


def sheet(**answers) -> dict:
    data = reference_sheet()
    for item, answer in answers.items():
        data["answers"][item] = answer
    return data


def _with_pairs(result, pairs: dict[str, float]):
    lanes = {name: m.model_copy(update={"pair_friction": pairs[name], "pair_friction_values": [pairs[name]]})
             for name, m in result.metrics.lanes.items()}
    return dataclasses.replace(result, metrics=result.metrics.model_copy(update={"lanes": lanes}))


def _never_stops(result, lane: str):
    """`result` as a run whose `lane` kept sliding to the end of the window (no sustained stop)."""
    lanes = dict(result.metrics.lanes)
    lanes[lane] = lanes[lane].model_copy(update={"stop": Stop(stopped=False, detail="no sustained stop within "
                                                                                     "the measurement window")})
    return dataclasses.replace(result, metrics=result.metrics.model_copy(update={"lanes": lanes}))


def test_b1_needs_exactly_the_changed_lanes_not_a_subset(measured):
    runs = sheet_results(measured)
    reference = grade_sheet(parse_sheet(sheet()), runs)
    assert reference.item("B1").verdict == "credit"  # the table exercise changes the low lane's pair only
    # No lane at all: the empty set is a subset of every answer, and earns nothing.
    empty = grade_sheet(parse_sheet(sheet(B1={"lanes": [], "explanation": "neither changes"})), runs)
    assert (empty.item("B1").verdict, empty.item("B1").score) == ("no_credit", 0)
    # An engine whose table exercise changed both pairs: naming one of them is half the answer, not the answer.
    both = {**runs, "sheet.table_exercise": _with_pairs(runs["sheet.table_exercise"], {"low": 0.3, "high": 0.9})}
    partial = grade_sheet(parse_sheet(sheet()), both)
    assert "high" in partial.item("B1").expected and "low" in partial.item("B1").expected, partial.item("B1")
    assert (partial.item("B1").verdict, partial.item("B1").score) == ("no_credit", 0)
    full = grade_sheet(parse_sheet(sheet(B1={"lanes": ["low", "high"], "explanation": "both pairs change"})), both)
    assert full.item("B1").verdict == "credit"


@pytest.mark.parametrize("lane", ["low", "high"])
def test_b2_is_inconclusive_when_a_baseline_lane_never_stops(measured, lane):
    runs = sheet_results(measured)
    assert grade_sheet(parse_sheet(sheet()), runs).item("B2").verdict == "credit"
    doctored = {**runs, BASELINE: _never_stops(runs[BASELINE], lane)}
    b2 = grade_sheet(parse_sheet(sheet()), doctored).item("B2")
    assert (b2.verdict, b2.score, b2.max_score) == ("inconclusive", 0, 0), b2
    assert "no sustained stop" in b2.measured
