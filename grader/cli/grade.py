"""`grader grade SHEET`: grade one prediction sheet on this machine, running the cases it needs through the engine."""

from __future__ import annotations

import json
import re
import sys
import time
from pathlib import Path

import click

from grader.core.states import ExecutionMode, values
import yaml
from pydantic import ValidationError

from rubric import (Variant, VariantPoolError, cases_to_run, describe_errors, draw_pool, grade_sheet,
                    load_rubric, load_variant_space, one_factor_findings, parse_sheet, sheet_files)
from rubric.exports import grades_csv, gradescope_results
from rubric.variants import complete_parameters
from worker import run_cases

CONFIG_SUFFIXES = (".yaml", ".yml", ".json")
EXIT_INCOMPLETE = 2


def run_cases_locally(specs, out_root: Path, mode: str, progress) -> dict:
    """Run cases in case processes on this machine (the one expensive dependency; tests replace this function)."""
    return run_cases(specs, out_root, mode=mode, progress=progress)


def _read(path: Path):
    try:  # YAML is a superset of JSON: one reader for both, refusing numbers the service cannot hold by their field
        return sheet_files.load_yaml(path.read_text())
    except OSError as exc:
        raise click.ClickException(f"{path}: cannot read YAML/JSON: {exc}") from None
    except sheet_files.SheetTextError as exc:
        raise click.ClickException(f"{path}: cannot read YAML/JSON: {exc.field}: {exc.rule}") from None


def load_sheet_data(sheet_file: Path, configs_dir: Path | None) -> dict:
    """The sheet's data with configs from CONFIGS_DIR (ROLE.yaml|json) merged in; a role given twice is an error."""
    data = _read(sheet_file)
    if not isinstance(data, dict):
        raise click.ClickException(f"{sheet_file}: a sheet is a mapping (lesson, student, answers, configs)")
    if configs_dir is None:
        return data
    configs = data.setdefault("configs", {})
    if not isinstance(configs, dict):
        raise click.ClickException(f"{sheet_file}: configs must be a mapping of role to case spec")
    for path in sorted(p for p in configs_dir.iterdir() if p.suffix in CONFIG_SUFFIXES):
        if path.stem in configs:
            raise click.ClickException(f"configs.{path.stem}: given both in {sheet_file} and as {path}")
        configs[path.stem] = _read(path)
    return data


UNNAMED_VARIANT = "v0-0"


def load_variant(value: str | None, lesson: str, space_version: str | None) -> Variant | None:
    """--variant: a pool variant id (v<seed>-<n>: the n-th variant drawn from the lesson's variant space with that
    seed, as an assignment's pool draws it), or its parameters as JSON (inline or a .json/.yaml file): either
    {"id": ..., "parameters": {...}} as `grader assignment variants list --json` prints one, or the bare parameters
    (the ones left out keep the lesson's value; its id is then v0-0)."""
    if value is None:
        return None
    try:
        if re.fullmatch(r"v[0-9]+-[0-9]+", value):
            seed, n = (int(part) for part in value[1:].split("-", 1))
            return draw_pool(load_variant_space(lesson, space_version), seed=seed, k=n).variants[n - 1]
        data = yaml.safe_load(value) if value.lstrip().startswith("{") else _read(Path(value))
        if not isinstance(data, dict):
            raise click.BadParameter("a variant id (v7-3) or a JSON object of parameters", param_hint="--variant")
        if "parameters" in data:
            return Variant(id=data.get("id", UNNAMED_VARIANT), lesson=lesson, parameters=data["parameters"])
        return Variant(id=UNNAMED_VARIANT, lesson=lesson, parameters=complete_parameters(data))
    except (ValueError, LookupError, yaml.YAMLError, VariantPoolError) as exc:
        detail = "\n  ".join(describe_errors(exc)) if isinstance(exc, ValidationError) else str(exc)
        raise click.BadParameter(detail, param_hint="--variant") from None


def _echo_report(report) -> None:
    for item in report.items:
        click.echo(f"{item.id:3s} {item.verdict:21s} {item.score:g}/{item.max_score:g}  {item.question}")
        click.echo(f"    {item.feedback}")
    click.echo(f"total: {report.total:g} / {report.max_total:g} (rubric {report.lesson} v{report.rubric_version}, "
               f"sha256 {report.rubric_hash[:12]})")


@click.command()
@click.argument("sheet_file", metavar="SHEET", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--configs", "configs_dir", type=click.Path(exists=True, file_okay=False, path_type=Path),
              help="Folder of case specs named by role (table_exercise.yaml, extension.json, N2.yaml, ...).")
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Folder for the case evidence, report.json, results.json (Gradescope) and grades.csv.")
@click.option("--json", "as_json", is_flag=True, help="Print the full grade report as JSON on stdout.")
@click.option("--rubric-version", default=None, help="Rubric version to grade under (default: the latest).")
@click.option("--mode", type=click.Choice(values(ExecutionMode)), default="warm", show_default=True)
@click.option("--variant", "variant_value", default=None, metavar="ID|JSON",
              help="Grade under a lab variant: a pool variant id (v7-3, drawn from the variant space by its seed) or "
                   "its parameters as JSON, inline or a file (default: the lesson's shipped cases).")
@click.option("--variant-space", "space_version", default=None,
              help="The variant space version a variant id is drawn from (default: the latest).")
def grade(sheet_file: Path, configs_dir: Path | None, out_dir: Path, as_json: bool, rubric_version: str | None,
          mode: str, variant_value: str | None, space_version: str | None) -> None:
    """Grade a prediction SHEET against cases measured on this machine; prints each item and the total."""
    started = time.perf_counter()
    data = load_sheet_data(sheet_file, configs_dir)
    try:
        sheet = parse_sheet(data)
    except ValidationError as exc:
        raise click.ClickException(f"{sheet_file}: invalid sheet:\n  " + "\n  ".join(describe_errors(exc))) from None
    try:
        rubric = load_rubric(sheet.lesson, rubric_version)
    except LookupError as exc:
        raise click.ClickException(str(exc)) from None
    variant = load_variant(variant_value, sheet.lesson, space_version)

    # Human progress goes to stderr so that --json leaves stdout machine-readable.
    log = lambda message: click.echo(message, err=True)  # noqa: E731
    if variant is not None:
        log(f"variant {variant.id}: " + ", ".join(f"{k}={v:g}" for k, v in sorted(variant.parameters.items())))
    for finding in one_factor_findings(sheet, rubric, variant).values():
        log(("config " if finding.ok else "config NOT RUN: ") + finding.describe())
    specs = cases_to_run(sheet, rubric, variant)
    log(f"running {len(specs)} cases ({mode}): {', '.join(s.name for s in specs)}")
    results = run_cases_locally(specs, out_dir / "cases", mode,
                                lambda r: log(f"  {r.spec.name}: {r.status} on {r.backend} in {r.wall_s:.1f} s"
                                              + (f" ({r.error})" if r.error else "")))
    report = grade_sheet(sheet, results, rubric, variant)

    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "report.json").write_text(report.model_dump_json(indent=2))
    (out_dir / "results.json").write_text(
        json.dumps(gradescope_results(report, time.perf_counter() - started), indent=2))
    (out_dir / "grades.csv").write_text(grades_csv([(sheet.student, report)]))
    if as_json:
        click.echo(report.model_dump_json(indent=2))
    else:
        _echo_report(report)
    log(f"report.json, results.json and grades.csv in {out_dir}")
    if not report.complete:
        log("some items could not be measured (see not_measured items); exit status 2")
        sys.exit(EXIT_INCOMPLETE)
