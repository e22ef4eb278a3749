"""`grader lesson`: the installed lessons, and whether a lesson can be used by a course (issue 45, item 6)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from grader.core.states import Backend, ExecutionMode, values
from rubric.lesson import LessonNotFound, lesson_names, load_lesson
from rubric.lesson import lesson as installed_lesson
from rubric.lesson_check import check_lesson

from .check import run_check


@click.group()
def lesson() -> None:
    """The lessons this service grades (found by entry point, rubric.lesson)."""


@lesson.command("list")
def list_lessons() -> None:
    """Every installed lesson: its name, title and rubric versions."""
    for name in lesson_names():
        found = installed_lesson(name)
        click.echo(f"{name}  {found.title('en')}  (rubric versions {', '.join(found.rubric_files()) or 'none'}; "
                   f"languages {', '.join(found.languages)}; {found.origin})")


@lesson.command("check")
@click.argument("name_or_path")
@click.option("--run/--no-run", default=True, show_default=True,
              help="Also run the lesson's lab check on real Genesis (its check cases) and require it to pass.")
@click.option("--backend", type=click.Choice(values(Backend)), default="cpu", show_default=True)
@click.option("--mode", type=click.Choice(values(ExecutionMode)), default="warm", show_default=True)
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("out/lesson-check"),
              show_default=True)
def check(name_or_path: str, run: bool, backend: str, mode: str, out_dir: Path) -> None:
    """Validate a lesson before a course uses it: its declaration, every rubric version (schema, reviewed
    tolerances, a scoring rule per item), audit tolerances, variant spaces and the texts of each language it teaches
    in; then its lab check on the CPU. NAME_OR_PATH: an installed lesson's name (L03), or the .py file (or folder
    holding lesson.py) that declares LESSON. Exit status 0 only when nothing is wrong."""
    try:
        found = installed_lesson(name_or_path) if not _looks_like_path(name_or_path) else load_lesson(
            Path(name_or_path))
    except LessonNotFound as exc:
        raise click.ClickException(str(exc)) from None
    click.echo(f"lesson {found.name}: {found.title('en')} ({found.origin})")
    problems = check_lesson(found)
    for problem in problems:
        click.echo(f"  PROBLEM {problem}")
    if problems:
        click.echo(f"{found.name}: {len(problems)} problem{'s' if len(problems) != 1 else ''}; nothing was run")
        sys.exit(1)
    click.echo(f"  files: rubric versions {', '.join(found.rubric_files())}, audit tolerances "
               f"{', '.join(found.audit_files()) or 'none'}, variant spaces {', '.join(found.variant_files()) or 'none'}"
               f"; texts in {', '.join(found.languages)}: no problem")
    if not run:
        click.echo(f"{found.name}: no problem (its lab check was not run: --no-run)")
        return
    report, _ = run_check(backend=backend, render=False, mode=mode, jobs=1, out_dir=out_dir, overrides=[],
                          lesson=found)
    click.echo("\n" + report.render_text())
    sys.exit(0 if report.passed else 1)


def _looks_like_path(text: str) -> bool:
    return "/" in text or text.endswith(".py") or Path(text).exists()
