"""Class-level item analysis of graded reports: share with credit, mean score, discrimination, common wrong answers.

Pure statistics over GradeReports (one per student: the caller picks which attempt counts). Discrimination is the
corrected item-total correlation (item score against the total of the *other* items), the usual classical-test
statistic; it is None where either side has no variance (everyone scored the same), never a made-up number.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np
from pydantic import BaseModel

from .scoring.scorer import GradeReport

TOP_WRONG_ANSWERS = 3


class WrongAnswer(BaseModel):
    prediction: str
    count: int


class ItemStats(BaseModel):
    id: str
    part: str
    kind: str
    question: str
    points: float
    n: int  # reports in which the item counted (inconclusive items are left out, as in the total)
    credit_share: float | None
    mean_score: float | None
    discrimination: float | None
    wrong_answers: list[WrongAnswer]
    verdicts: dict[str, int]


class ScoreBin(BaseModel):
    low: float
    high: float
    count: int


class ClassAnalysis(BaseModel):
    n_reports: int
    max_total: float | None
    mean_total: float | None
    median_total: float | None
    distribution: list[ScoreBin]
    items: list[ItemStats]


def _correlation(a: np.ndarray, b: np.ndarray) -> float | None:
    if len(a) < 2 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def score_distribution(totals: Sequence[float], max_total: float, bins: int = 10) -> list[ScoreBin]:
    """Counts of totals in `bins` equal-width bins over [0, max_total]; the top bin includes full marks."""
    if max_total <= 0:
        return []
    edges = np.linspace(0.0, max_total, bins + 1)
    counts, _ = np.histogram(np.asarray(totals, dtype=float), bins=edges)
    return [ScoreBin(low=float(lo), high=float(hi), count=int(c)) for lo, hi, c in zip(edges[:-1], edges[1:], counts)]


def class_analysis(reports: Sequence[GradeReport]) -> ClassAnalysis:
    """Item statistics and the score distribution of one report per student."""
    if not reports:
        return ClassAnalysis(n_reports=0, max_total=None, mean_total=None, median_total=None, distribution=[], items=[])
    totals = np.array([r.total for r in reports], dtype=float)
    max_total = max(r.max_total for r in reports)
    items = []
    for first in reports[0].items:
        grades = [next((i for i in r.items if i.id == first.id), None) for r in reports]
        counted = [(g, r) for g, r in zip(grades, reports) if g is not None and g.verdict != "inconclusive"]
        scores = np.array([g.score for g, _ in counted], dtype=float)
        rest = np.array([r.total - g.score for g, r in counted], dtype=float)
        wrong = Counter(g.prediction for g, _ in counted if g.verdict == "no_credit")
        items.append(ItemStats(
            id=first.id, part=first.part, kind=first.kind, question=first.question, points=first.points,
            n=len(counted),
            credit_share=float(np.mean([g.verdict == "credit" for g, _ in counted])) if counted else None,
            mean_score=float(scores.mean()) if counted else None,
            discrimination=_correlation(scores, rest),
            wrong_answers=[WrongAnswer(prediction=p, count=c) for p, c in wrong.most_common(TOP_WRONG_ANSWERS)],
            verdicts=dict(Counter(g.verdict for g in grades if g is not None)),
        ))
    return ClassAnalysis(n_reports=len(reports), max_total=max_total, mean_total=float(totals.mean()),
                         median_total=float(np.median(totals)), distribution=score_distribution(totals, max_total),
                         items=items)
