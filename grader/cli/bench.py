"""`grader bench`: wall time per case, isolated vs warm, measured side by side in one run (medians and ratios)."""

from __future__ import annotations

from pathlib import Path

import click

from grader.benchmark.cases import BenchFailure, bench_cases, format_cases


@click.command()
@click.option("--cases", default="N1,N2,N3,N4,N5", show_default=True, help="Comma-separated case names.")
@click.option("--repeats", type=click.IntRange(1, 20), default=3, show_default=True)
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("out/bench"),
              show_default=True)
def bench(cases: str, repeats: int, out_dir: Path) -> None:
    """Time each case as an isolated process and in one warm case process, interleaved, and print medians and ratios."""
    try:
        figures = bench_cases([name.strip() for name in cases.split(",")], repeats, out_dir,
                              log=lambda line: click.echo(line, err=True))
    except BenchFailure as exc:
        raise click.ClickException(str(exc)) from exc
    click.echo("")
    for line in format_cases(figures):
        click.echo(line)
