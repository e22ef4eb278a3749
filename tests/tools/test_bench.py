"""`python -m tools.bench`: its statistics, target verdicts, tables, the class it submits and the JSON it writes
(fast, from recorded figures), and one bounded real run."""

from __future__ import annotations

import json
import math

import pytest
from click.testing import CliRunner

from tools.bench import stats, tables
from tools.bench.classroom import class_sheets, distinct_configs

SUBMISSION = {"stack": "embedded", "repeats": 3, "case_runs": 9, "first_s": 90.0, "cold_s": 12.0, "reused_s": 0.4,
              "cold_samples_s": [12.0], "reused_samples_s": [0.4], "cold_cases_s": 7.5, "cold_rubric_s": 0.3,
              "cold_complete_s": 18.0, "reused_complete_s": 0.9}
CLASS = [{"stack": "embedded", "workers": 1, "slots": 2, "submissions": 20, "accepted": 20, "refused": 0,
          "graded": 20, "failed": 0, "lost": 0, "distinct_configs": 36, "two_factor": 2, "posting_s": 3.0,
          "total_s": 60.0, "per_submission_s": 3.0},
         {"stack": "redis-pg", "workers": 1, "slots": 2, "submissions": 20, "accepted": 20, "refused": 0,
          "graded": 20, "failed": 0, "lost": 0, "distinct_configs": 36, "two_factor": 2, "posting_s": 3.0,
          "total_s": 40.0, "per_submission_s": 2.0, "complete_s": 42.5, "warm_up_wait_s": 12.5},
         {"stack": "redis-pg", "workers": 2, "slots": 1, "submissions": 20, "accepted": 19, "refused": 1,
          "graded": 17, "failed": 1, "lost": 1, "distinct_configs": 36, "two_factor": 2, "posting_s": 3.0,
          "total_s": 50.0, "per_submission_s": 2.5, "complete_s": 55.0, "warm_up_wait_s": 20.0,
          "profile": {"runs": {"runs": 171, "reused_at_admission": 110, "finished_when_measured": 10,
                               "reused_in_worker": 30, "measured": 21, "measured_keys": 20, "measured_twice": 1,
                               "failed_runs": 0, "case_s": 30.0,
                               "first_measured_s": 0.5, "last_measured_s": 44.0, "grading_wait_median_s": 0.25,
                               "grading_wait_max_s": 3.0,
                               "per_worker": {"1": {"measured": 11, "case_s": 16.0, "reused": 14},
                                              "2": {"measured": 10, "case_s": 14.0, "reused": 16}},
                               "by_case": {"extension": {"measured": 11, "fresh_scenes": 10, "wall_s": 20.0,
                                                         "build_s": 9.0, "steps_s": 8.5}}},
                      "tasks": [{"run_case_run": {"count": 25, "busy_s": 20.0},
                                 "grade_submission": {"count": 9, "busy_s": 4.5}}, {}],
                      "queues": {"samples": 100, "runs_peak": 40, "checks_peak": 12, "grades_peak": 3,
                                 "runs_last_waiting_s": 41.5}}}]
MEMORY = {"stack": "embedded", "cases": 54, "first_mb": 1000.0, "last_mb": 1020.0, "max_mb": 1030.0,
          "growth_pct": 2.0, "last_by_process_mb": {"1 celery": 100.0, "2 python": 920.0}, "samples": []}
API = [{"stack": "embedded", "clients": 50, "requests_per_client": 20, "requests": 1000, "p50_ms": 20.0,
        "p95_ms": 60.0, "p99_ms": 90.0, "max_ms": 120.0, "errors": 0, "error_examples": [], "requests_per_s": 300.0,
        "by_path": {"/v1/submissions/{id}": {"requests": 500, "p50_ms": 20.0, "p95_ms": 60.0, "p99_ms": 90.0,
                                              "max_ms": 100.0}}}]


def test_percentiles_interpolate_between_ranks_and_growth_is_relative():
    values = [float(v) for v in range(1, 101)]
    assert stats.percentile(values, 50) == pytest.approx(50.5)
    assert stats.percentile(values, 95) == pytest.approx(95.05)
    assert stats.percentile([3.0], 99) == 3.0
    assert math.isnan(stats.percentile([], 50))
    assert stats.growth_pct(1000, 1050) == pytest.approx(5.0)
    summary = stats.latency_summary([0.01, 0.02, 0.03])
    assert summary["requests"] == 3 and summary["p50_ms"] == pytest.approx(20.0) and summary["max_ms"] == 30.0


def test_verdicts_say_met_or_by_how_much_missed_and_when_a_run_was_smaller_than_the_target():
    assert tables.verdict("submission_reused_s", 0.4) == "met (<= 0.5 s)"
    assert tables.verdict("submission_cold_s", 11.0) == "MISSED by 6 s (2.2x the 5 s)"
    assert tables.verdict("class_s", 60.0, partial="20 of 200") == "met (<= 90 s) (20 of 200)"
    assert tables.verdict("api_p95_ms", math.nan) == "no figure"


def test_tables_print_every_figure_beside_its_target():
    text = "\n".join([*tables.format_submission(SUBMISSION), *tables.format_class(CLASS),
                      *tables.format_memory(MEMORY), *tables.format_api(API)])
    assert "fully reused                       0.40 s   met (<= 0.5 s)" in text
    assert "cold (force_rerun)                12.00 s   MISSED by 7 s (2.4x the 5 s)" in text
    assert "until the last case finished   7.50 s, then the rubric 0.30 s" in text
    assert "lab check stored                18.00 s after the POST (evaluated after the grade)" in text
    assert "lab check stored                 0.90 s after the POST" in text
    assert "redis-pg, 1 worker: last lab check stored 42.5 s after the first POST" in text
    assert "redis-pg, 2 workers: waited 20.0 s after start for the case slots to warm up" in text
    assert "projected to 200: 600 s from 20" in text and "embedded / redis-pg (1 worker): 1.50x" in text
    # per worker count: subs, refused, graded, failed, lost; the ratio two workers / one; the issue-35 target
    assert "  redis-pg         2     1    20       1     17      1    1      36        2     3.0s    50.0s" in text
    assert "redis-pg: 2 workers / 1 worker: 1.25x (50.0 s against 40.0 s)" in text
    assert ("200 sheets, 40 configs on two CPU workers <= 40 s (redis-pg): MISSED by 460 s (12.5x the 40 s) "
            "(projected to 200: 500 s from 20) (1 LOST)") in text
    assert "the host's cores split among the workers" in text
    assert ("runs 171 of 19 submissions: 110 reused at admission, "
            "10 finished in the queue when their case was measured, 30 reused in a worker, 21 measured (20 distinct, "
            "1 measured again concurrently), 0 failed") in text
    assert "by worker: worker 1 11 (16.0 s), worker 2 10 (14.0 s)" in text
    assert "extension 11, 10 fresh, 20.0 = 9.0 + 8.5 + 2.5 s" in text
    assert ("worker 1 tasks: grade_submission 9 x 0.50 s = 4.5 s, run_case_run 25 x 0.80 s = 20.0 s; busy 24.5 s, "
            "45% of its 1 slot(s) until the last lab check") in text
    assert "worker 2 tasks: none; busy 0.0 s" in text
    assert "at most 40 runs, 3 grades, 12 lab checks waiting; runs last waiting at 41.5 s" in text
    assert "max    met (<= 1536 MB) (54 of 500 cases)" in text and "growth +2.0%" in text
    assert "MISSED by 10 ms (1.2x the 50 ms)" in text and "/v1/submissions/{id}" in text


def test_the_class_shares_the_baseline_and_carries_40_distinct_configs_and_a_tenth_two_factor_sheets():
    import rubric

    sheets = class_sheets([f"s{i:03d}" for i in range(200)])
    assert distinct_configs(sheets) == 40
    findings = [rubric.one_factor_findings(rubric.parse_sheet(s), rubric.load_rubric()) for s in sheets[:20]]
    broken = [i for i, f in enumerate(findings) if not all(finding.ok for finding in f.values())]
    assert broken == [9, 19]  # every tenth sheet moves the table as well as its friction


def test_the_json_holds_each_part_under_its_name_with_the_command(tmp_path, monkeypatch):
    from tools.bench import run
    from tools.bench.cli import bench

    def fake(options, *, save, log):
        assert options.class_size == 20 and options.memory_cases == 50 and options.api_clients == 7
        save("submission", SUBMISSION)
        save("api", API)
        return tables.format_submission(SUBMISSION)

    monkeypatch.setattr(run, "run_bench", fake)
    out = tmp_path / "b.json"
    result = CliRunner().invoke(bench, ["--quick", "--only", "submission,api", "--api-clients", "7", "--json",
                                        str(out)])
    assert result.exit_code == 0, result.output
    figures = json.loads(out.read_text())
    assert figures["quick"] is True and figures["submission"]["reused_s"] == 0.4 and figures["api"][0]["clients"] == 50
    assert {"command", "started_utc", "host", "cpus"} <= figures.keys()
    assert "fully reused" in result.output
    refused = CliRunner().invoke(bench, ["--only", "cases,everything"])
    assert refused.exit_code != 0 and "unknown part everything" in refused.output


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_tiny_real_run_measures_a_case_three_ways_and_writes_its_json(tmp_path):
    from tools.bench.cli import bench

    result = CliRunner().invoke(bench, ["--quick", "--only", "cases", "--cases", "N3", "--repeats", "1", "--out",
                                        str(tmp_path)])
    assert result.exit_code == 0, result.output
    row = json.loads((tmp_path / "bench.json").read_text())["cases"]["per_case"]["N3"]
    assert 0 < row["stepping_s"] <= row["reused_s"] and row["warm_s"] > 0 and row["isolated_s"] > row["warm_s"]
    assert "reused/stepping" in result.output and "machine: shared" in result.output


FIGURES = {"stack": "embedded", "repeats": 2, "submission_id": 5, "cold_cases_s": 14.05, "cold_complete_s": 14.62,
           "complete_over_cases": 14.62 / 14.05, "cases_samples_s": [], "complete_samples_s": [],
           "png": {"figures": 18, "cpu_s": 7.23, "wall_s": 7.5, "bytes": 2_110_000, "cpu_samples_s": []},
           "series": {"cpu_s": 0.065, "bytes": 61_400, "gzip_bytes": 6_300, "served_bytes": 61_400,
                      "api_cpu_per_request_s": 0.048, "api_wall_per_request_s": 0.06, "runs": 9}}


def test_the_figures_table_sets_both_ways_beside_the_issue_24_targets():
    """(the figures recorded by `python -m tools.bench --quick --only figures`, 2026-11-26, docs/benchmark.md)"""
    text = "\n".join(tables.format_figures(FIGURES))
    assert "(a) 18 PNGs drawn on the server     7.23 s CPU     2.11 MB   MISSED by 6.73 s (14.5x the 0.5 s)" in text
    assert "(b) series built for the browser   0.065 s CPU    0.061 MB (6 kB gzipped)   met (<= 0.5 s)" in text
    assert "served by the API               0.048 s CPU per request" in text
    assert "report complete (lab check stored)  14.62 s after the POST, cases 14.05 s: 1.04x   met (<= 1.5 x)" in text


def test_the_class_runs_once_per_worker_count_with_the_cores_split_among_the_workers(tmp_path, monkeypatch):
    """--class-workers and --class-slots reach the class part: a stack per (stack, worker count), embedded at one
    worker only, each worker with the host's cores split among the workers unless the slots are given."""
    import contextlib

    from tools.bench import run
    from tools.bench.classroom import slots_per_worker
    from tools.bench.cli import bench

    assert [slots_per_worker(n, cores=2) for n in (1, 2, 3)] == [2, 1, 1]
    assert [slots_per_worker(n, cores=8) for n in (1, 2, 3)] == [8, 4, 2]
    started = []

    @contextlib.contextmanager
    def stack(kind, folder, *, students, workers, worker_env):
        started.append((kind, workers, worker_env["WORKER_CONCURRENCY"], students))
        yield kind

    def bench_class(kind, size, log, *, slots):
        return CLASS[2] | {"stack": kind, "workers": started[-1][1], "slots": slots}

    monkeypatch.setattr(run, "service_stack", stack)
    monkeypatch.setattr(run, "bench_class", bench_class)
    monkeypatch.setattr(run, "slots_per_worker", lambda workers: slots_per_worker(workers, cores=2))
    result = CliRunner().invoke(bench, ["--only", "class", "--class-size", "20", "--class-stacks", "embedded,redis-pg",
                                        "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert started == [("embedded", 1, "2", 20), ("redis-pg", 1, "2", 20), ("redis-pg", 2, "1", 20)]
    rows = json.loads((tmp_path / "bench.json").read_text())["class"]
    assert [(r["stack"], r["workers"], r["slots"]) for r in rows] == [("embedded", 1, 2), ("redis-pg", 1, 2),
                                                                      ("redis-pg", 2, 1)]
    assert "200 sheets, 40 configs on two CPU workers <= 40 s (redis-pg): MISSED" in result.output

    started.clear()
    result = CliRunner().invoke(bench, ["--only", "class", "--class-size", "20", "--class-stacks", "redis-pg",
                                        "--class-workers", "2", "--class-slots", "3", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert started == [("redis-pg", 2, "3", 20)] and "as given (--class-slots)" in result.output
    for bad in ("0", "two", ""):
        refused = CliRunner().invoke(bench, ["--only", "class", "--class-workers", bad, "--out", str(tmp_path)])
        assert refused.exit_code != 0 and "--class-workers" in refused.output


def test_the_embedded_stack_refuses_a_second_worker_before_starting_anything(tmp_path):
    from tools.harness.stack import service_stack

    with pytest.raises(ValueError, match="the embedded stack runs one worker"), \
            service_stack("embedded", tmp_path, workers=2):
        pass
    assert not list(tmp_path.iterdir())


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_tiny_class_on_two_real_workers_is_graded_by_both_and_every_post_is_accounted_for(tmp_path):
    """The class part's real path on two Celery worker processes (one case slot each, one broker): both warm up,
    both take the class's runs, every POST ends graded, and the profile reads both workers' logs."""
    from tests import services
    from tools.bench.classroom import bench_class
    from tools.harness.stack import ServiceUnavailable, service_stack

    lines = []
    try:
        with service_stack("redis-pg", tmp_path, students=4, workers=2, worker_env={"WORKER_CONCURRENCY": "1"},
                           redis_url=services.SPARE_REDIS_URL, postgres_url=services.PG_ADMIN_URL) as stack:
            assert len(stack.workers) == 2 and stack.workers[0] is stack.worker
            assert stack.worker_log(1).name == "worker-2.log"
            row = bench_class(stack, 4, log=lines.append, slots=1)
    except ServiceUnavailable as exc:
        services.unavailable("Redis or PostgreSQL", exc)
    assert (row["workers"], row["slots"], row["submissions"], row["accepted"]) == (2, 1, 4, 4)
    assert (row["graded"], row["failed"], row["lost"], row["refused"]) == (4, 0, 0, 0)
    assert sum("case slots warm" in line for line in lines) == 2  # each worker's own warm-up line
    runs = row["profile"]["runs"]
    assert runs["runs"] == 4 * 9 and runs["measured"] >= 1
    assert sum(c["measured"] for c in runs["by_case"].values()) == runs["measured"]
    assert runs["reused_at_admission"] + runs["finished_when_measured"] + runs["reused_in_worker"] + runs["measured"] \
        + runs["failed_runs"] == 36
    tasks = row["profile"]["tasks"]
    assert len(tasks) == 2 and all(t.get("run_case_run", {}).get("count", 0) >= 1 for t in tasks)
    assert sum(t["grade_submission"]["count"] for t in tasks if "grade_submission" in t) >= 4
    assert sum(w["measured"] + w["reused"] for w in runs["per_worker"].values()) == \
        runs["measured"] + runs["reused_in_worker"]
    text = "\n".join(tables.format_class([row]))
    assert "redis-pg         2     1     4       0      4      0    0" in text
    assert "200 sheets, 40 configs on two CPU workers <= 40 s (redis-pg): " in text and "from 4)" in text


def test_a_post_answered_2xx_that_never_ends_is_counted_lost_and_a_refused_post_refused(tmp_path, monkeypatch):
    """The class's accounting on a stack whose service answers as told: one sheet graded, one answered 202 and never
    graded nor failed (lost, once nothing has been stored for the stall limit), one refused."""
    import os
    from types import SimpleNamespace

    from sqlalchemy.orm import Session

    from grader.core.db import make_engine, migrate
    from grader.core.models import Submission, User, utcnow
    from tools.bench import classroom
    from tools.harness.stack import _people
    from worker.warm_gate import OPENED

    url = f"sqlite:///{tmp_path / 'grader.db'}"
    migrate(url)
    engine = make_engine(url)
    _, names = _people(engine, 3)

    class Service:
        def __init__(self, who):
            self.who = who

        def submit(self, sheet):
            if self.who == "s002":
                raise RuntimeError("HTTP 429: too many submissions")
            with Session(engine) as session:
                user = session.query(User).filter_by(name=self.who).one()
                row = Submission(course_id=user.course_id, student_id=user.id, lesson="L03", sheet=sheet,
                                 status="graded" if self.who == "s000" else "running",
                                 graded_at=utcnow() if self.who == "s000" else None)
                session.add(row)
                session.commit()
                return {"id": row.id}

    (tmp_path / "worker.log").write_text(f"[...] all 1 {OPENED} after 1.0 s: consuming cpu\n")
    worker = SimpleNamespace(poll=lambda: None, pid=os.getpid(), returncode=None)
    stack = SimpleNamespace(kind="redis-pg", engine=engine, students=names, env={"BROKER_URL": ""},
                            data_dir=tmp_path, workers=[worker], worker=worker, client=Service,
                            worker_log=lambda index: tmp_path / "worker.log")
    monkeypatch.setattr(classroom, "STALL_LIMIT_S", 1.5)
    lines = []
    row = classroom.bench_class(stack, 3, log=lines.append, slots=1)
    engine.dispose()
    assert (row["submissions"], row["accepted"], row["refused"], row["graded"], row["failed"], row["lost"]) == \
        (3, 2, 1, 1, 0, 1)
    assert row["lost_ids"] == [2] and row["refused_examples"] == ["s002: HTTP 429: too many submissions"]
    assert any(line.startswith("  LOST: 1 submission(s)") for line in lines)
    text = "\n".join(tables.format_class([row]))
    assert "  redis-pg         1     1     3       1      1      0    1" in text
