"""Submission validation on the real app: clear JSON errors naming the field, nothing half-stored, one queue per backend."""

from __future__ import annotations

import copy
import json

import pytest
from sqlalchemy import func, select

from tests.factories import reference_sheet


def counts() -> tuple[int, int]:
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Submission

    with new_session() as session:
        return (session.scalar(select(func.count()).select_from(Submission)),
                session.scalar(select(func.count()).select_from(CaseRun)))


def post(api, body, who="alice", *, content: str | None = None):
    if content is not None:
        headers = {**api.as_(who), "content-type": "application/json"}
        return api.client.post("/v1/submissions", content=content, headers=headers)
    return api.client.post("/v1/submissions", json=body, headers=api.as_(who))


def test_a_valid_sheet_stores_case_runs_then_queues_each_on_its_backend(api):
    response = post(api, {"sheet": reference_sheet()})
    assert response.status_code == 202, response.text
    body = response.json()
    assert body["status"] == "running" and body["progress"]["queued"] == body["progress"]["total"] > 0
    runs = api.client.get(f"/v1/submissions/{body['id']}/case-runs", headers=api.as_("alice")).json()
    assert sorted(api.sent) == sorted((r["id"], 1, "cpu") for r in runs)
    assert {"sheet.extension", "sheet.table_exercise"} <= {r["name"] for r in runs}  # configs travel in the sheet
    assert counts() == (1, len(runs))
    events = api.client.get(f"/v1/submissions/{body['id']}/events", headers=api.as_("alice")).json()
    assert events[0]["state"] == "submitted" and all(e["at"] for e in events)


def rejected(api, response, field_part: str):
    assert response.status_code == 422, response.text
    body = response.json()
    assert body["detail"] and any(field_part in e["field"] and e["rule"] for e in body["errors"]), body
    assert counts() == (0, 0) and api.sent == []
    return body


def test_unknown_top_level_field_is_named(api):
    rejected(api, post(api, {"sheet": reference_sheet(), "sheeet": {}}), "sheeet")


def test_unknown_backend_is_named(api):
    rejected(api, post(api, {"sheet": reference_sheet(), "backend": "gpu"}), "backend")


def test_invalid_config_is_named_by_its_path(api):
    sheet = reference_sheet()
    sheet["configs"]["extension"]["substeps"] = 0
    rejected(api, post(api, {"sheet": sheet}), "sheet.configs.extension.substeps")


def test_a_config_with_a_fractional_step_count_is_refused(api):
    sheet = reference_sheet()
    sheet["configs"]["extension"]["dt"] = 0.013  # 1.5 / 0.013 is not a whole number of outer steps
    body = rejected(api, post(api, {"sheet": sheet}), "sheet.configs.extension.duration")
    assert any("integer number of outer steps" in e["rule"] for e in body["errors"])


def test_wrong_answer_type_is_named(api):
    sheet = reference_sheet()
    sheet["answers"]["A3"]["agree"] = "yes"
    rejected(api, post(api, {"sheet": sheet}), "sheet.answers.A3.agree")


@pytest.mark.parametrize("value", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_numbers_are_refused(api, value):
    text = json.dumps({"sheet": reference_sheet()}).replace('"pair_friction": 0.5', f'"pair_friction": {value}')
    assert value in text
    response = post(api, None, content=text)
    rejected(api, response, "sheet.answers.C5.pair_friction")


def test_oversized_body_gets_413_before_parsing(api):
    from grader.core.settings import settings

    sheet = copy.deepcopy(reference_sheet())
    sheet["answers"]["A5"]["explanation"] = "x" * (settings.max_body_bytes + 10)
    response = post(api, {"sheet": sheet})
    assert response.status_code == 413
    assert response.json()["errors"][0]["field"] == "body"
    assert counts() == (0, 0)


def test_openapi_documents_bodies_and_errors(api):
    spec = api.client.get("/openapi.json").json()
    post_op = spec["paths"]["/v1/submissions"]["post"]
    assert "SubmissionCreate" in json.dumps(post_op["requestBody"])
    for code in ("401", "403", "413", "422"):
        assert "ErrorBody" in json.dumps(post_op["responses"][code]), code
    assert "HTTPBearer" in spec["components"]["securitySchemes"]
