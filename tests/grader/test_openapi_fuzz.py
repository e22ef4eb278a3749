"""Schemathesis over the app's own OpenAPI, in-process (ASGI), as a student and as an instructor: every operation,
every check (schemathesis.toml), a bounded and reproducible number of examples. Any 5xx, undocumented status or
content type, or body that breaks its documented schema fails the test.

The database holds the course's people and one submission of alice's, so ids and names the generator tries can
reach real rows (404 otherwise). Enqueueing is recorded by the `api` fixture, never sent.
"""

from __future__ import annotations

from collections import Counter

import pytest
import schemathesis
from hypothesis import HealthCheck, settings

from tests.factories import ROOT, reference_sheet

EXAMPLES = 200  # per operation and caller; with the coverage phase, about 2 minutes on the 2-core machine
REQUESTS: Counter = Counter()


def _schema():
    from grader.main import app

    config = schemathesis.Config.from_path(ROOT / "schemathesis.toml")
    return schemathesis.openapi.from_asgi("/openapi.json", app, config=config)


schema = _schema()


@pytest.fixture
def seeded(api, monkeypatch):
    """The `api` fixture's people plus one submission of alice's; the submission limit out of the way."""
    from grader.settings import settings as grader_settings

    # The generator submits far more often than a student may; the limit itself is tested in test_hostile_input.
    monkeypatch.setattr(grader_settings, "rate_limit_submissions", "100000/minute")
    created = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert created.status_code == 202, created.text
    return api


# One test per operation and caller; its database is made once and kept across that test's examples.
@pytest.mark.parametrize("caller", ["alice", "prof"])
@schema.parametrize()
@settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])
def test_no_operation_answers_5xx_or_off_its_schema(case, seeded, caller):
    response = case.call_and_validate(headers=seeded.as_(caller))
    REQUESTS[(caller, case.operation.label, response.status_code // 100)] += 1


@pytest.fixture(scope="module", autouse=True)
def report_request_counts():
    """How much the fuzzing did, printed with -s (issue 12 counts requests per operation)."""
    yield
    operations = {op for _, op, _ in REQUESTS}
    by_class = Counter()
    for (_, _, cls), n in REQUESTS.items():
        by_class[f"{cls}xx"] += n
    print(f"\nschemathesis: {sum(REQUESTS.values())} requests over {len(operations)} operations, "
          f"by status class {dict(sorted(by_class.items()))}")
