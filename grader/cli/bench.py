"""`grader bench`: wall time per case, isolated vs warm, measured side by side in one run (medians and ratios)."""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import click

from rubric import get_case


@click.command()
@click.option("--cases", default="N1,N2,N3,N4,N5", show_default=True, help="Comma-separated case names.")
@click.option("--repeats", type=click.IntRange(1, 20), default=3, show_default=True)
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("out/bench"),
              show_default=True)
def bench(cases: str, repeats: int, out_dir: Path) -> None:
    """Time each case as an isolated process and in one warm case process, interleaved, and print medians and ratios."""
    from worker import WarmCaseProcess, run_case

    specs = [get_case(name.strip()) for name in cases.split(",")]
    wall = {(s.name, m): [] for s in specs for m in ("isolated", "warm")}
    steps = {s.name: [] for s in specs}
    with WarmCaseProcess() as warm:
        # The warm process's first case pays import + init + kernel loading; time it separately, not as a case.
        started = time.perf_counter()
        first = warm.run(specs[0], out_dir / "warmup")
        click.echo(f"warm case process start-up (first case {specs[0].name}): {time.perf_counter() - started:.2f} s")
        if not first.ok:
            raise click.ClickException(f"warm-up failed: {first.error}")
        for r in range(repeats):
            # Interleave modes so machine noise hits both alike.
            for spec in specs:
                for mode in ("isolated", "warm"):
                    kwargs = {"warm_process": warm} if mode == "warm" else {}
                    result = run_case(spec, out_dir / f"{mode}-{r}" / spec.name, mode=mode, **kwargs)
                    if not result.ok:
                        raise click.ClickException(f"{spec.name} ({mode}) failed: {result.error}")
                    wall[(spec.name, mode)].append(result.wall_s)
                    if mode == "warm":
                        steps[spec.name].append(result.provenance.timings.steps_s)
                    click.echo(f"  repeat {r + 1}/{repeats} {spec.name:4s} {mode:8s} {result.wall_s:7.2f} s", err=True)
    click.echo(f"\nmedian wall time per case over {repeats} repeats (s):")
    click.echo(f"{'case':6s} {'isolated':>9s} {'warm':>7s} {'ratio':>7s} {'stepping':>9s}")
    for spec in specs:
        iso, wrm = statistics.median(wall[(spec.name, "isolated")]), statistics.median(wall[(spec.name, "warm")])
        click.echo(f"{spec.name:6s} {iso:9.2f} {wrm:7.2f} {iso / wrm:6.1f}x {statistics.median(steps[spec.name]):9.3f}")
    total_iso = sum(statistics.median(wall[(s.name, "isolated")]) for s in specs)
    total_warm = sum(statistics.median(wall[(s.name, "warm")]) for s in specs)
    click.echo(f"{'all':6s} {total_iso:9.2f} {total_warm:7.2f} {total_iso / total_warm:6.1f}x")
