"""Item analysis on hand-made reports whose statistics are known by construction."""

import pytest

from rubric import class_analysis
from rubric.scoring import GradeReport


def _report(student: str, scores: dict[str, tuple[str, str]]) -> GradeReport:
    """scores: item id -> (verdict, prediction); every item is worth 1 point."""
    items = [{"id": i, "question": f"question {i}", "part": "A", "kind": "measured", "points": 1.0,
              "score": 1.0 if v == "credit" else 0.0, "max_score": 0.0 if v == "inconclusive" else 1.0,
              "verdict": v, "prediction": p, "expected": "x", "feedback": "", "evidence": {}, "backends": {},
              "tolerances": {}} for i, (v, p) in scores.items()]
    total = sum(i["score"] for i in items)
    return GradeReport.model_validate({
        "lesson": "L03", "student": student, "rubric_version": "2", "rubric_hash": "h", "engine_version": "1.3.3",
        "total": total, "max_total": sum(i["max_score"] for i in items), "complete": True, "items": items,
        "config_findings": []})


def test_share_mean_discrimination_and_wrong_answers():
    reports = [
        _report("a", {"X": ("credit", "low"), "Y": ("credit", "up"), "Z": ("credit", "k")}),
        _report("b", {"X": ("credit", "low"), "Y": ("credit", "up"), "Z": ("no_credit", "m")}),
        _report("c", {"X": ("no_credit", "high"), "Y": ("no_credit", "down"), "Z": ("credit", "k")}),
        _report("d", {"X": ("no_credit", "high"), "Y": ("inconclusive", "up"), "Z": ("no_credit", "m")}),
    ]
    analysis = class_analysis(reports)
    x, y, z = (next(i for i in analysis.items if i.id == k) for k in "XYZ")
    assert (x.n, x.credit_share, x.mean_score) == (4, 0.5, 0.5)
    assert [(w.prediction, w.count) for w in x.wrong_answers] == [("high", 2)]
    # Y is inconclusive for d: left out of its statistics, as it is left out of d's total.
    assert (y.n, y.credit_share) == (3, pytest.approx(2 / 3)) and y.verdicts == {"credit": 2, "no_credit": 1, "inconclusive": 1}
    # X against the rest (Y+Z): a, b score high on both; c, d low on X. Corrected item-total correlation, by hand:
    # X = [1, 1, 0, 0], rest = [2, 1, 1, 0] -> r = 0.7071.
    assert x.discrimination == pytest.approx(0.70710678)
    assert analysis.n_reports == 4 and analysis.mean_total == pytest.approx((3 + 2 + 1 + 0) / 4)
    assert [b.count for b in analysis.distribution if b.count] == [1, 1, 1, 1]


def test_no_variance_gives_no_discrimination_rather_than_a_number():
    reports = [_report(s, {"X": ("credit", "low"), "Y": (v, "up")}) for s, v in (("a", "credit"), ("b", "no_credit"))]
    x = class_analysis(reports).items[0]
    assert x.credit_share == 1.0 and x.discrimination is None


def test_no_reports():
    analysis = class_analysis([])
    assert analysis.n_reports == 0 and analysis.items == [] and analysis.mean_total is None
