"""grader.check_report on real Genesis results: the HTML report and text summary carry the verdict, every condition and
its evidence, the metric tables and figures, and never let a student-supplied name through unescaped."""

from __future__ import annotations

import base64
import dataclasses
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from grader import check_report as report
from lessons.l03 import figures
from rubric import CaseResult, case_metrics, get_case
from tests.factories import heavy_imports

EVIL = "<script>alert('x')</script>"


def _condition(cid: str, title: str, passed: bool, evidence: str) -> SimpleNamespace:
    # Duck-typed like rubric.check's conditions: the report depends on attributes, not on a class.
    return SimpleNamespace(id=cid, title=title, passed=passed, evidence=evidence)


CONDITIONS = [
    _condition("A1", "every contact case covers 1.5 s", True, "N1: 150 x 0.01 s; N3: 75 x 0.02 s"),
    _condition("B1", "low lane travels farther than high lane", True, "0.410 m > 0.224 m"),
    _condition("B2", "lowering table friction moves only the low lane", False, "low +0.264 m; high +0.000 m"),
]


@pytest.fixture(scope="module")
def pngs(measured, tmp_path_factory) -> list[Path]:
    out = tmp_path_factory.mktemp("report_figures")
    return figures.contact_figures(measured, out)


def _write(tmp_path, measured, pngs, **kw) -> str:
    args = dict(verdict=False, conditions=CONDITIONS, results=measured, figures=pngs) | kw
    path = report.write_check_report(tmp_path, **args)
    assert path == tmp_path / "report.html"
    return path.read_text(encoding="utf-8")


def test_verdict_names_the_failed_condition(tmp_path, measured, pngs):
    text = _write(tmp_path, measured, pngs)
    assert "L03 CHECK: FAILED \u2014 lowering table friction moves only the low lane" in text
    assert "class='verdict fail'" in text
    assert "L03 CHECK: PASSED" not in text


def test_passed_verdict(tmp_path, measured, pngs):
    text = _write(tmp_path, measured, pngs, verdict=True, conditions=CONDITIONS[:2])
    assert "L03 CHECK: PASSED" in text
    assert "class='verdict pass'" in text


def test_every_condition_with_its_evidence_and_result(tmp_path, measured, pngs):
    text = _write(tmp_path, measured, pngs)
    for c in CONDITIONS:
        row = re.search(rf"<tr><td>{c.id}</td><td>{re.escape(c.title)}</td><td>(.*?)</td><td>(.*?)</td></tr>", text)
        assert row, c.title
        assert ("passed" if c.passed else "FAILED") in row.group(1)
        assert row.group(2) == c.evidence.replace(">", "&gt;")


def test_metric_tables_hold_measured_values(tmp_path, measured, pngs):
    text = _write(tmp_path, measured, pngs)
    rows = {row["case"]: row for row in report.contact_rows(measured)}
    assert set(rows) == {"N1", "N2", "N3", "N4", "N5"}
    assert rows["N3"]["samples"] == "75" and rows["N1"]["samples"] == "150"
    assert rows["N5"]["substep_dt (s)"] == "0.0025" and rows["N5"]["internal updates"] == "600"
    proxy_mm = (get_case("N3").expected_center_z - measured["N3"].arrays["z"].min()) * 1e3
    assert rows["N3"]["penetration proxy (mm)"] == f"{proxy_mm:.2f}"
    assert f"<td class='num'>{rows['N3']['penetration proxy (mm)']}</td>" in text
    lanes = report.lane_rows(measured)
    assert [(r["run"], r["lane"], r["effective pair \u03bc (engine)"]) for r in lanes] == [
        ("friction-baseline", "low", "0.50"),
        ("friction-baseline", "high", "0.80"),
        ("friction-table-0.30", "low", "0.30"),
        ("friction-table-0.30", "high", "0.80"),
        ("friction-baseline-colors-swapped", "low", "0.50"),
        ("friction-baseline-colors-swapped", "high", "0.80"),
    ]
    assert all(float(r["stop distance (m)"]) > 0 for r in lanes)
    assert "rgb(255, 128, 0)" in text  # the low lane's orange Surface colour as its table swatch


def test_lane_that_did_not_stop_is_reported_as_such(measured):
    result = measured["friction-baseline"]
    arrays = dict(result.arrays, low_vx=np.full_like(result.arrays["low_vx"], 1.0))
    doctored = dataclasses.replace(result, arrays=arrays, metrics=case_metrics(result.spec, arrays))
    rows = report.lane_rows({"friction-baseline": doctored})
    low = next(r for r in rows if r["lane"] == "low")
    assert low["stop distance (m)"] == report.NOT_STOPPED == "not stopped within the measured window"
    assert low["stop time (s)"] == report.NOT_STOPPED


def test_provenance_per_case(tmp_path, measured, pngs):
    text = _write(tmp_path, measured, pngs)
    rows = {row["case"]: row for row in report.provenance_rows(measured)}
    assert set(rows) == set(measured)
    for name, row in rows.items():
        p = measured[name].provenance
        assert row["actual backend"] == p.actual_backend == "cpu"
        assert row["execution mode"] == "warm, fresh scene"  # the fixture builds a scene per case
        assert f"genesis {p.versions['genesis']}" in row["versions"]
        assert row["rendering"].startswith("SKIP")
    assert "import " in text and "SKIP (0 frames)" in text


def test_figures_embedded_as_base64_png(tmp_path, measured, pngs):
    text = _write(tmp_path, measured, pngs)
    embedded = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', text)
    assert len(embedded) == len(pngs) == 2
    assert base64.b64decode(embedded[0]) == pngs[0].read_bytes()
    assert "src=\"http" not in text and "<script" not in text


def test_figures_linked_relatively_when_not_embedded(tmp_path, measured):
    local = figures.contact_figures(measured, tmp_path / "figs")
    text = _write(tmp_path, measured, local, embed=False)
    for path in local:
        assert f'src="figs/{path.name}"' in text
    assert "base64" not in text


def test_malicious_case_name_and_condition_are_escaped(tmp_path, measured):
    spec = measured["N1"].spec.model_copy(update={"name": EVIL})
    evil = {EVIL: dataclasses.replace(measured["N1"], spec=spec),
            "crash": CaseResult(spec=get_case("N2"), status="failed", error=f"boom {EVIL}", stderr=EVIL)}
    conditions = [_condition(EVIL, EVIL, False, EVIL)]
    text = _write(tmp_path, measured, [], results=evil, conditions=conditions)
    assert EVIL not in text
    assert "<script" not in text
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt;" in text


def test_failed_case_keeps_its_row_and_error(tmp_path, measured):
    crash = CaseResult(spec=get_case("N2"), status="timeout", error="case ran past 900 s")
    results = {"N1": measured["N1"], "N2": crash}
    text = _write(tmp_path, measured, [], results=results)
    rows = {row["case"]: row for row in report.contact_rows(results)}
    assert rows["N2"]["status"] == "timeout" and "penetration proxy (mm)" not in rows["N2"]
    assert "case ran past 900 s" in text and "Failed cases" in text


def test_missing_figure_is_stated(tmp_path, measured):
    text = _write(tmp_path, measured, [tmp_path / "gone.png"])
    assert "figure missing: gone.png" in text


def test_figures_and_report_never_import_genesis_or_torch():
    assert heavy_imports(["worker.figures", "lessons.l03.figures", "grader.check_report"]) == []
