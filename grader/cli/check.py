"""`grader check`: run a lesson's lab check cases on real Genesis and print every condition with its evidence
(`--lesson`, an installed lesson's name: L03 by default)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import click

from grader.core.states import Backend, ExecutionMode, values

from rubric import CaseResult, with_backend
from rubric.check import OutputLocation
from rubric.lesson import Lesson
from rubric.lesson import lesson as installed_lesson
from rubric.lesson import lesson_names

from grader.check_report import write_check_report
from worker import run_cases

from .case import load_spec_file


def output_location(out_dir: Path) -> OutputLocation:
    """Generated files must stay under out_dir, and out_dir must be outside version control (or ignored by it)."""
    out_dir = out_dir.resolve()
    files = [p for p in out_dir.rglob("*") if p.is_file()]
    npz = sum(p.suffix == ".npz" for p in files)
    png = sum(p.suffix == ".png" for p in files)
    where = f"{npz} .npz and {png} .png files under {out_dir}"
    top = subprocess.run(["git", "-C", str(out_dir), "rev-parse", "--show-toplevel"], capture_output=True, text=True)
    if top.returncode != 0:
        return OutputLocation(passed=npz > 0, evidence=f"{where}; not inside a git work tree")
    ignored = subprocess.run(["git", "-C", str(out_dir), "check-ignore", "-q", str(out_dir)]).returncode == 0
    tracked = subprocess.run(
        ["git", "-C", str(out_dir), "ls-files", "--", str(out_dir)], capture_output=True, text=True
    ).stdout.strip()
    passed = npz > 0 and ignored and not tracked
    detail = "ignored by git" if ignored else "NOT ignored by git: generated evidence could be committed"
    if tracked:
        detail += f"; tracked files present: {tracked.splitlines()[:3]}"
    return OutputLocation(passed=passed, evidence=f"{where}; inside work tree {top.stdout.strip()}, {detail}")


def run_check(
    *, backend: str, render: bool, mode: str, jobs: int, out_dir: Path, overrides: list[Path], echo=click.echo,
    lesson: Lesson | None = None,
):
    """Run a lesson's check cases (L03's unless `lesson` is given: `grader lesson check`), write figures and reports
    into out_dir, return (CheckReport, results)."""
    from worker.figures import lab_figures  # lazy: matplotlib (~0.7 s) only for `grader check`, not `grader --help`

    lesson = lesson or installed_lesson("L03")
    specs = {name: with_backend(lesson.cases[name], backend=backend, render=render) for name in lesson.check_cases}
    for path in overrides:
        spec = load_spec_file(path)
        if spec.name not in specs:
            raise click.ClickException(f"{path}: case name {spec.name!r} is not one of the check's cases {list(specs)}")
        specs[spec.name] = spec
        echo(f"using {path} for case {spec.name}")
    out_dir.mkdir(parents=True, exist_ok=True)
    echo(f"{lesson.name} check: {len(specs)} cases on backend={backend}, rendering={'on' if render else 'off'}, mode={mode}")
    echo("(the first Genesis run on a fresh machine compiles kernels for ~100 s)")
    started, count = time.perf_counter(), [0]

    def progress(result: CaseResult) -> None:
        count[0] += 1
        status = "ok" if result.ok else f"{result.status.upper()}: {result.error}"
        echo(f"  [{count[0]}/{len(specs)}] {result.spec.name:20s} {result.wall_s:6.1f} s  {status}")

    results = run_cases(specs.values(), out_dir / "cases", mode=mode, jobs=jobs, progress=progress)
    echo(f"ran {len(results)} cases in {time.perf_counter() - started:.1f} s")
    figures = lab_figures(results, out_dir / "figures")
    report = lesson.evaluate_check(results, outputs=output_location(out_dir))
    (out_dir / "check.json").write_text(report.model_dump_json(indent=2))
    (out_dir / "check.txt").write_text(report.render_text() + "\n")
    html = write_check_report(out_dir, verdict=report.passed, conditions=report.conditions, results=results,
                              figures=figures, lesson=lesson)
    echo(f"figures: {len(figures)} PNGs in {out_dir / 'figures'}; report: {html}")
    return report, results


@click.command()
@click.option("--backend", type=click.Choice(values(Backend)), default="cpu", show_default=True)
@click.option("--render/--no-render", default=False, help="Add a camera and return real initial/final frames.")
@click.option("--mode", type=click.Choice(values(ExecutionMode)), default="isolated", show_default=True,
              help="isolated: one process per case (the lesson's contract); warm: one long-lived Genesis process.")
@click.option("--jobs", type=click.IntRange(1, 16), default=1, show_default=True, help="Parallel isolated processes.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("out/check"),
              show_default=True)
@click.option("--spec", "overrides", multiple=True, type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="A case spec JSON replacing the check case of the same name (repeatable).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON instead of text.")
@click.option("--lesson", "lesson_name", type=click.Choice(lesson_names()), default="L03", show_default=True,
              help="The installed lesson whose lab check runs (`grader lesson list`).")
def check(backend, render, mode, jobs, out_dir, overrides, as_json, lesson_name) -> None:
    """Run the lesson's check cases (L03: N1-N4 and both friction runs), evaluate every condition of its lab check,
    print <LESSON> CHECK: PASSED or FAILED."""
    echo = (lambda *a, **k: click.echo(*a, err=True, **k)) if as_json else click.echo
    report, _ = run_check(backend=backend, render=render, mode=mode, jobs=jobs, out_dir=out_dir,
                          overrides=list(overrides), echo=echo, lesson=installed_lesson(lesson_name))
    click.echo(report.model_dump_json(indent=2) if as_json else "\n" + report.render_text())
    if not as_json:
        click.echo(f"\nevidence: {out_dir / 'cases'}  report: {out_dir / 'report.html'}")
    sys.exit(0 if report.passed else 1)
