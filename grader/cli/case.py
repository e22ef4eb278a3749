"""`grader case`: list, show, schema and run single case specs of the installed lessons."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from grader.core.states import ExecutionMode, values
from pydantic import TypeAdapter, ValidationError

from rubric import CaseSpec, describe_errors, parse_case
from rubric.lesson import lesson, lesson_names
from worker import run_case


@click.group()
def case() -> None:
    """Inspect and run single simulation cases."""


def _cases() -> dict[str, object]:
    """Every installed lesson's cases by name (lesson by lesson; a case name is one lesson's)."""
    return {name: spec for declared in map(lesson, lesson_names()) for name, spec in declared.cases.items()}


@case.command("list")
def list_cases() -> None:
    """List the installed lessons' case names."""
    for name, spec in _cases().items():
        click.echo(f"{name:22s} {spec.kind:8s} dt={spec.dt} substeps={spec.substeps} duration={spec.duration}")


@case.command()
@click.argument("name")
@click.option("--derived", is_flag=True, help="Also print derived quantities (substep_dt, n_steps, ...).")
def show(name: str, derived: bool) -> None:
    """Print a lesson's case spec as JSON (runnable with `grader case run`)."""
    cases = _cases()
    if name not in cases:
        raise click.ClickException(f"unknown case {name!r}; known cases: {', '.join(cases)}")
    click.echo(json.dumps(cases[name].model_dump(mode="json", exclude_computed_fields=not derived), indent=2))


@case.command()
def schema() -> None:
    """Print the JSON schema of a case spec."""
    click.echo(json.dumps(TypeAdapter(CaseSpec).json_schema(), indent=2))


def load_spec_file(path: Path):
    """A case spec from a JSON file, or a ClickException naming every bad field."""
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise click.ClickException(f"{path}: cannot read JSON: {exc}") from None
    try:
        return parse_case(data)
    except ValidationError as exc:
        raise click.ClickException(f"{path}: invalid case spec:\n  " + "\n  ".join(describe_errors(exc))) from None


@case.command()
@click.argument("spec_file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path))
@click.option("--mode", type=click.Choice(values(ExecutionMode)), default="isolated", show_default=True)
def run(spec_file: Path, out_dir: Path, mode: str) -> None:
    """Run one case spec on real Genesis and keep its evidence in OUT."""
    spec = load_spec_file(spec_file)
    click.echo(f"running {spec.name} ({spec.kind}, backend={spec.backend}, {spec.n_steps} steps, mode={mode}) ...")
    result = run_case(spec, out_dir, mode=mode)
    if not result.ok:
        click.echo(f"{spec.name}: {result.status.upper()}: {result.error}", err=True)
        click.echo(f"evidence kept in {out_dir} (spec.json, stdout.txt, stderr.txt)", err=True)
        sys.exit(1)
    p = result.provenance
    click.echo(f"{spec.name}: OK on {p.actual_backend} ({p.device_name}) in {result.wall_s:.1f} s; "
               f"arrays: {', '.join(sorted(result.arrays))}")
    click.echo(f"evidence in {out_dir}")
