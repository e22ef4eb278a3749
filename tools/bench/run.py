"""Runs the chosen parts of `python -m tools.bench` in order, saving each part's figures as soon as it has them,
and returns the printed tables."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from tools.bench import tables
from tools.bench.bounded import bench_bounded, format_bounded
from tools.bench.cases import bench_cases, format_cases
from tools.bench.classroom import bench_class, slots_per_worker
from tools.bench.figures import bench_figures
from tools.bench.load import bench_api
from tools.bench.memory import bench_memory
from tools.bench.reads import format_reads, run_reads
from tools.bench.slots import format_slots, run_slots
from tools.harness.stack import service_stack
from tools.bench.submission import bench_submission, reference_sheet, time_submission
from tools.bench.variants import bench_variants, format_variants


@dataclass
class BenchOptions:
    parts: tuple[str, ...]
    cases: list[str]
    repeats: int
    class_size: int
    class_stacks: list[str]
    memory_cases: int
    api_clients: int
    api_requests: int
    api_stacks: list[str]
    api_think_s: tuple[float, ...]
    out_dir: Path
    quick: bool = False
    variants_k: int = 16
    class_workers: tuple[int, ...] = (1, 2)
    class_slots: int = 0  # case slots per worker in the class; 0: classroom.slots_per_worker
    api_cpus: str | None = None  # reads: the CPUs the API processes are pinned to (the readers get the others)


def _graded_submission(stack) -> tuple[int, str]:
    """A graded submission to read (the reference sheet), and who may read it."""
    who = stack.students[0]
    state = time_submission(stack.client(who), reference_sheet(), worker=stack.worker).state
    return state["id"], who


def _api(stack, o: BenchOptions, bench_api, log) -> list[dict]:
    """One load per think time, on one graded submission."""
    submission_id, who = _graded_submission(stack)
    return [bench_api(stack, submission_id, who, o.api_clients, o.api_requests, think_s=think, log=log)
            for think in o.api_think_s]


def run_bench(o: BenchOptions, *, save: Callable[[str, object], None], log: Callable[[str], None]) -> list[str]:
    out: list[str] = []
    services = o.out_dir / "services"
    if "cases" in o.parts:
        log("== cases: isolated, warm, reused, stepping")
        figures = bench_cases(o.cases, o.repeats, o.out_dir / "cases", log=log)
        save("cases", figures)
        out += [*format_cases(figures), *tables.format_case_targets(figures), ""]
    api_rows: list[dict] = []
    # One submission, API latency and memory share a stack: each measures from its own start.
    if {"submission", "figures", "memory"} & set(o.parts) or ("api" in o.parts and "embedded" in o.api_stacks):
        with service_stack("embedded", services, students=1) as stack:
            if "submission" in o.parts:
                log("== one submission (embedded)")
                figures = bench_submission(stack, o.repeats, log=log)
                save("submission", figures)
                out += [*tables.format_submission(figures), ""]
            if "figures" in o.parts:
                log("== a submission's figures: PNGs on the server, series for the browser (embedded)")
                figures = bench_figures(stack, o.repeats, log=log)
                save("figures", figures)
                out += [*tables.format_figures(figures), ""]
            if "api" in o.parts and "embedded" in o.api_stacks:
                log(f"== API latency, {o.api_clients} clients (embedded)")
                api_rows += _api(stack, o, bench_api, log)
                save("api", api_rows)
            if "memory" in o.parts:
                log(f"== worker memory over {o.memory_cases} cases (embedded)")
                figures = bench_memory(stack, o.memory_cases, log=log)
                save("memory", figures)
                out += [*tables.format_memory(figures), ""]
    for kind in (k for k in o.api_stacks if k != "embedded" and "api" in o.parts):
        with service_stack(kind, services, students=1) as stack:
            log(f"== API latency, {o.api_clients} clients ({kind})")
            api_rows += _api(stack, o, bench_api, log)
            save("api", api_rows)
    if api_rows:
        out += [*tables.format_api(api_rows), ""]
    if "reads" in o.parts:
        out += [*format_reads(run_reads(o, services, graded_submission=_graded_submission, save=save, log=log)), ""]
    if "class" in o.parts:
        rows = []
        for kind in o.class_stacks:
            # Several workers need a shared broker: the embedded stack (a filesystem broker) stays at one.
            if kind == "embedded" and any(n != 1 for n in o.class_workers):
                log("== the embedded stack runs one worker (its filesystem broker serves one): more only on redis-pg")
            for workers in (n for n in o.class_workers if kind != "embedded" or n == 1):
                slots = o.class_slots or slots_per_worker(workers)
                log(f"== a class of {o.class_size} ({kind}, {workers} CPU worker(s) x {slots} case slot(s))")
                with service_stack(kind, services, students=o.class_size, workers=workers,
                                   worker_env={"WORKER_CONCURRENCY": str(slots)}) as stack:
                    rows.append(bench_class(stack, o.class_size, log=log, slots=slots))
                save("class", rows)
        out += [*tables.format_class(rows, explicit_slots=bool(o.class_slots)), ""]
    if "bounded" in o.parts:
        log("== the worst sheet the caps admit: check, save, export, import, submit (in-process)")
        figures = bench_bounded(o.out_dir / "bounded", max(o.repeats, 5), log=log)
        save("bounded", figures)
        out += [*format_bounded(figures), ""]
    if "slots" in o.parts:
        figures = run_slots(o.out_dir / "slots", o.repeats, log=log)
        save("slots", figures)
        out += [*format_slots(figures, tables.verdict), ""]
    if "variants" in o.parts:
        log(f"== per-student variants: a pool of {o.variants_k}, a class of {o.class_size} with and without (redis-pg)")
        with service_stack("redis-pg", services, students=o.class_size, warm=True) as stack:
            figures = bench_variants(stack, o.variants_k, o.class_size, o.repeats, log=log)
        save("variants", figures)
        out += [*format_variants(figures, tables.verdict), ""]
    if out and out[-1] == "":
        out.pop()
    return out + ["machine: shared (other jobs may run on the same cores); compare figures within this run only"]
