"""`python -m tools.bench`: cases by execution path, one submission, a class, worker memory and API latency, measured
side by side in one run (medians and ratios), printed with the issue-12 targets and written as JSON.

Run from the repository root (`make bench`): tools/ is development tooling, not installed with the grader."""

from __future__ import annotations

import json
import os
import platform
import sys
from datetime import UTC, datetime
from pathlib import Path

import click

from tools.bench import run
from tools.bench.cases import BenchFailure
from tools.harness.stack import ServiceUnavailable

PARTS = ("cases", "submission", "figures", "class", "memory", "api", "reads", "bounded", "slots", "variants")
# --quick: the same measurements, smaller, in a few minutes.
FULL = {"cases": "N1,N2,N3,N4,N5", "repeats": 3, "class_size": 200, "memory_cases": 500, "api_requests": 20,
        "variants": 16}
QUICK = {"cases": "N1,N3,N5", "repeats": 2, "class_size": 20, "memory_cases": 50, "api_requests": 10, "variants": 4}


def _parts(value: str) -> tuple[str, ...]:
    parts = tuple(p.strip() for p in value.split(",") if p.strip())
    unknown = [p for p in parts if p not in PARTS]
    if unknown:
        raise click.BadParameter(f"unknown part {', '.join(unknown)}; choose from {', '.join(PARTS)}")
    return parts


def _counts(value: str) -> tuple[int, ...]:
    try:
        counts = tuple(int(p) for p in value.split(",") if p.strip())
    except ValueError:
        counts = ()
    if not counts or any(not 1 <= n <= 16 for n in counts):
        raise click.BadParameter(f"{value!r}: comma-separated worker counts, each 1-16", param_hint="--class-workers")
    return counts


# -h as well as --help, as under the `grader` group it came from.
@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--quick", is_flag=True, help="Smaller everything, a few minutes: " + json.dumps(QUICK))
@click.option("--only", default=",".join(PARTS), show_default=True, help="Comma-separated parts to run.")
@click.option("--cases", default=None, help=f"Comma-separated case names (default {FULL['cases']}).")
@click.option("--repeats", type=click.IntRange(1, 20), default=None, help="Repeats per case and per submission.")
@click.option("--class-size", type=click.IntRange(1, 1000), default=None, help="Submissions in the class.")
@click.option("--class-stacks", default="embedded,redis-pg", show_default=True)
@click.option("--class-workers", default="1,2", show_default=True,
              help="CPU worker counts the class runs on, one after the other (redis-pg; embedded runs 1 only).")
@click.option("--class-slots", type=click.IntRange(0, 64), default=0, show_default=True,
              help="Case slots per worker in the class; 0: the host's cores split among the workers (at least 1).")
@click.option("--variants", "variants_k", type=click.IntRange(1, 64), default=None,
              help="Variants drawn for the pool (part variants).")
@click.option("--memory-cases", type=click.IntRange(1, 5000), default=None, help="Cases sampled for memory.")
@click.option("--api-clients", type=click.IntRange(1, 500), default=50, show_default=True)
@click.option("--api-stacks", default="embedded", show_default=True, help="Stacks the API load runs on.")
@click.option("--api-think", default="0,1", show_default=True,
              help="Seconds each reader pauses between reads, one load per value (0: back to back).")
@click.option("--api-cpus", default=None, metavar="CPUS",
              help="Part reads: pin the API processes to these CPUs (taskset list, e.g. 1) and the readers to the "
                   "others, so that the API has cores of its own.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("out/bench"),
              show_default=True, help="Case folders and service data.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Where the figures go (default OUT/bench.json).")
def bench(quick: bool, only: str, cases: str | None, repeats: int | None, class_size: int | None, class_stacks: str,
          class_workers: str, class_slots: int, variants_k: int | None, memory_cases: int | None, api_clients: int,
          api_stacks: str, api_think: str, api_cpus: str | None, out_dir: Path, json_path: Path | None) -> None:
    """Measure, print a table per part with the targets met or missed, and write the figures as JSON."""
    size = QUICK if quick else FULL
    options = run.BenchOptions(
        parts=_parts(only), cases=[c.strip() for c in (cases or size["cases"]).split(",")],
        repeats=repeats or size["repeats"], class_size=class_size or size["class_size"],
        class_stacks=[s.strip() for s in class_stacks.split(",")], memory_cases=memory_cases or size["memory_cases"],
        api_clients=api_clients, api_requests=size["api_requests"],
        api_stacks=[s.strip() for s in api_stacks.split(",")],
        api_think_s=tuple(float(t) for t in api_think.split(",")),
        out_dir=out_dir, quick=quick, variants_k=variants_k or size["variants"],
        class_workers=_counts(class_workers), class_slots=class_slots, api_cpus=api_cpus)
    json_path = json_path or out_dir / "bench.json"
    report = {"command": " ".join(["python", "-m", "tools.bench", *sys.argv[1:]]), "quick": quick,
              "started_utc": datetime.now(UTC).isoformat(timespec="seconds"), "host": platform.node(),
              "cpus": os.cpu_count()}

    def save(part: str, figures) -> None:
        report[part] = figures
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(report, indent=2, default=str))

    try:
        tables = run.run_bench(options, save=save, log=lambda line: click.echo(line, err=True))
    except (BenchFailure, ServiceUnavailable) as exc:
        raise click.ClickException(f"{exc} (figures so far in {json_path})") from exc
    click.echo("")
    for line in tables:
        click.echo(line)
    click.echo(f"\nfigures: {json_path}")
