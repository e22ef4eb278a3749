"""`python -m tools.variant_space`: measure a sample of a lesson's variant space on real Genesis and say where its
relations hold (issue 47).

For each seed, the first N variants a pool of that seed would draw (rubric.draw_pool: the same variants, the same
order) each run the lesson's check cases in one warm case process (scenes reused, as a worker does) and are checked by
the lesson's own lab check under the space's grading rubric (rubric.check.evaluate with the variant), as a pool's
variant is. The report (rubric.variants.survey): the kept fraction per seed and overall, the drops by failed
condition, kept/measured per parameter value and per contact case's internal step, and the constraints that would
have removed the drops without losing a kept variant. `--json FILE` keeps every outcome.

    python -m tools.variant_space --space 2 --seeds 1,2,3 --per-seed 6
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import click

from rubric import load_rubric, load_variant_space, with_backend
from rubric.cases import CHECK_CASES
from rubric.check import OutputLocation, evaluate
from rubric.variants import draw_pool
from rubric.variants.survey import Outcome, checked_quantities, report_lines, survey
from worker import WarmCaseProcess

# The check's `outputs` condition is about where a student's lab run writes files; here the cases run in a temporary
# folder of this command, so it is not what a space is measured for.
OUTPUTS = OutputLocation(passed=True, evidence="measured by tools.variant_space into a temporary folder")


def measure_variant(process: WarmCaseProcess, variant, book, folder: Path, backend: str,
                    measured: dict[str, object] | None = None) -> Outcome:
    """Run `variant`'s check cases in `process` and evaluate the lesson's lab check on them. `measured` (spec JSON ->
    result) holds the cases run for earlier variants: a case with the very same spec is not run again, as the service
    reuses a measurement by content key (most variants share their contact cases)."""
    cases = variant.cases()
    measured = {} if measured is None else measured
    started = time.perf_counter()
    results = {}
    for name in CHECK_CASES:
        spec = with_backend(cases[name], backend=backend)
        key = spec.model_dump_json()
        if key not in measured:
            measured[key] = process.run(spec, folder / variant.id / name)
        results[name] = measured[key]
    report = evaluate(results, outputs=OUTPUTS, rubric=book, variant=variant)
    return Outcome(id=variant.id, parameters=variant.parameters, kept=report.passed,
                   failed=[c.id for c in report.failed], evidence={c.id: c.evidence for c in report.failed},
                   seconds=round(time.perf_counter() - started, 2))


@click.command()
@click.option("--lesson", default="L03", show_default=True)
@click.option("--space", "version", default=None, help="The variant space version (default: the latest).")
@click.option("--seeds", default="1,2,3", show_default=True, help="Comma-separated pool seeds.")
@click.option("--only", default=None, help="Comma-separated variant ids: measure only these of the seeds' draws.")
@click.option("--per-seed", type=click.IntRange(1, 64), default=6, show_default=True,
              help="Variants measured per seed: the first N a pool of that seed draws.")
@click.option("--backend", default="cpu", show_default=True)
@click.option("--json", "json_out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write every outcome and the survey as JSON here.")
def main(lesson: str, version: str | None, seeds: str, only: str | None, per_seed: int, backend: str,
         json_out: Path | None) -> None:
    """Measure the first PER_SEED variants of each seed's pool and report kept/dropped by condition and value."""
    space = load_variant_space(lesson, version)
    book = load_rubric(lesson, space.grading_rubric)
    seed_list = [int(s) for s in seeds.split(",") if s.strip()]
    click.echo(f"{lesson} variant space v{space.version} (rubric v{book.version}): {per_seed} variants of each of "
               f"seeds {', '.join(map(str, seed_list))}, {len(CHECK_CASES)} check cases each, backend {backend}")
    outcomes: dict[int, list[Outcome]] = {}
    started = time.perf_counter()
    measured: dict[str, object] = {}
    with tempfile.TemporaryDirectory(prefix="variant-space-") as tmp, WarmCaseProcess(reuse_scenes=True) as process:
        for seed in seed_list:
            pool = draw_pool(space, seed=seed, k=per_seed)
            outcomes[seed] = []
            for variant in pool.variants:
                if only and variant.id not in only.split(","):
                    continue
                outcome = measure_variant(process, variant, book, Path(tmp), backend, measured)
                outcomes[seed].append(outcome)
                click.echo(f"  {variant.id:10s} {'kept   ' if outcome.kept else 'dropped'} {outcome.seconds:6.1f} s"
                           + (f"  failed: {', '.join(outcome.failed)}" if outcome.failed else ""))
                for condition, text in outcome.evidence.items():
                    click.echo("\n".join(f"      {condition}: {line}" for line in text.splitlines()))
    total_s = time.perf_counter() - started
    every = [o for seed in seed_list for o in outcomes[seed]]
    result = survey(every, space.parameters, checked=checked_quantities(space.choices(), CHECK_CASES))
    click.echo("")
    for seed in seed_list:
        kept = sum(o.kept for o in outcomes[seed])
        click.echo(f"seed {seed}: kept {kept} of {len(outcomes[seed])}")
    for line in report_lines(result, f"{lesson} variant space v{space.version}, seeds {seeds}:"):
        click.echo(line)
    click.echo(f"measured {len(every)} variants in {total_s:.0f} s ({total_s / max(1, len(every)):.1f} s per variant; "
               f"{len(measured)} distinct cases run for {len(every) * len(CHECK_CASES)} checked)")
    if json_out is not None:
        json_out.write_text(json.dumps({
            "lesson": lesson, "space_version": space.version, "space_hash": space.content_hash, "seeds": seed_list,
            "per_seed": per_seed, "seconds": round(total_s, 1),
            "outcomes": {str(s): [o.model_dump(mode="json") for o in outcomes[s]] for s in seed_list},
            "survey": result.model_dump(mode="json")}, indent=2))
    sys.exit(0)


if __name__ == "__main__":
    main(prog_name="python -m tools.variant_space")
