"""A run's stored arrays are decoded once per process and kept by (evidence row, when it was stored): grading and the
lab check of a class read the same few measurements for every sheet. A row stored again is read afresh, and every
reader gets arrays of its own."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from sqlalchemy import select

from tests.factories import reference_sheet


def _store(run_id: int, value: float) -> None:
    """What the worker stores for a finished run: its evidence (arrays as the engine writes them), done and ok."""
    from grader.core import lifecycle
    from grader.core.db import new_session
    from grader.core.models import CaseRun
    from rubric import parse_case

    with new_session() as session:
        run = session.get(CaseRun, run_id)
        result = SimpleNamespace(out_dir=None, arrays={"t": np.arange(4.0), "x": np.full(4, value)},
                                 spec=parse_case(run.spec), provenance=None, metrics=None, stdout="", stderr="")
        lifecycle.store_evidence(session, run, result)
        run.status, run.result_status = "done", "ok"
        session.commit()


def _arrays(run_id: int) -> dict:
    from grader.core.db import new_session
    from grader.core.lifecycle import stored_result
    from grader.core.models import CaseRun

    with new_session() as session:
        return stored_result(session.get(CaseRun, run_id)).arrays


def test_stored_arrays_are_read_once_per_row_and_afresh_when_the_row_is_stored_again(api, monkeypatch):
    from grader.core import lifecycle
    from grader.core.models import CaseRun

    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    from grader.core.db import new_session

    with new_session() as session:
        run_id = session.scalar(select(CaseRun.id).where(CaseRun.submission_id == response.json()["id"],
                                                         CaseRun.name == "N1"))
    _store(run_id, 1.0)
    loads = []
    real_load = np.load
    monkeypatch.setattr(lifecycle.np, "load", lambda *a, **k: loads.append(1) or real_load(*a, **k))
    first = _arrays(run_id)
    first["x"][:] = 99.0  # a reader's own copy: changing it changes nothing stored
    again = _arrays(run_id)
    assert loads == [1] and again["x"].tolist() == [1.0] * 4 and again["t"].tolist() == [0.0, 1.0, 2.0, 3.0]
    _store(run_id, 2.0)  # a re-sent run's new try replaces the row: a new stored_at, read afresh
    assert _arrays(run_id)["x"].tolist() == [2.0] * 4 and loads == [1, 1]
