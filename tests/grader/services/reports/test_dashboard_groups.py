"""The dashboard's score distributions never mix maxima (one per assignment, one per maximum outside assignments),
and its submissions per day are the course's calendar days (issue 33)."""

from __future__ import annotations

from datetime import datetime
from types import SimpleNamespace

import pytest

from grader.core.schemas import CountedGradePublic
from grader.services.reports.dashboard import AssignmentGrades, per_day, score_groups


pytestmark = pytest.mark.clock("2026-11-27T12:00:00Z")


def _counted(student: str, score: float, max_score: float) -> CountedGradePublic:
    return CountedGradePublic(student=student, submission_id=1, attempt=1, submitted_at=datetime(2026, 1, 1),
                              late_seconds=0, raw_score=score, max_score=max_score, penalty=0, counted_score=score)


def test_checkpoint_attempts_and_sheets_get_a_distribution_each():
    checkpoints = AssignmentGrades(id=3, title="Week 3 checkpoints", part="checkpoints", due_at=datetime(2026, 12, 1),
                                   counted_attempt="best", page="/assignments/3",
                                   grades=[_counted("a", 7, 8), _counted("b", 8, 8), _counted("c", 6, 8)])
    empty = checkpoints.model_copy(update={"id": 4, "grades": []})
    free = [SimpleNamespace(total=t, max_total=30.0) for t in (27.5, 30.0)] + [SimpleNamespace(total=7.0,
                                                                                              max_total=8.0)]
    groups = score_groups([checkpoints, empty], free)
    assert [(g.assignment_id, g.max_total, g.n) for g in groups] == [(3, 8, 3), (None, 8, 1), (None, 30, 2)]
    assert (groups[0].median, groups[0].mean) == (7, 7)
    assert groups[2].median == 28.75  # the two sheets alone: not "median 7.25 of 30" with the checkpoint mixed in
    for g in groups:
        assert g.distribution[-1].high == g.max_total and sum(b.count for b in g.distribution) == g.n


def test_submissions_per_day_are_counted_in_the_courses_zone():
    at = [datetime(2026, 11, 26, 20, 0), datetime(2026, 11, 26, 23, 0), datetime(2026, 11, 27, 1, 0)]  # naive UTC
    submissions = [SimpleNamespace(created_at=t) for t in at]
    assert per_day(submissions, "UTC") == {"2026-11-26": 2, "2026-11-27": 1}
    # 20:00 UTC is 01:30 the next day in Kolkata (+05:30); so is 23:00
    assert per_day(submissions, "Asia/Kolkata") == {"2026-11-27": 3}
    assert per_day(submissions, "America/Los_Angeles") == {"2026-11-26": 3}
