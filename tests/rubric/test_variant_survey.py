"""The variant space survey (issue 47, rubric.variants.survey): from measured outcomes, the kept fraction, the drops by
condition, kept/measured per value and per contact case's internal step, and the rule that removes the drops without
losing a kept variant. The pattern is the issue's: every drop ran N1 at an internal step finer than 0.01 s."""

from __future__ import annotations

from rubric.variants import draw_pool, load_variant_space
from rubric.variants.survey import Outcome, report_lines, survey

SPACE = load_variant_space("L03", "1")


def outcomes() -> list[Outcome]:
    """Sixteen variants of v1 with the measured pattern: kept exactly when N1's internal step is 0.01 s, but one."""
    out = []
    for v in draw_pool(SPACE, 4242, 16).variants:
        n1_step = v.parameters["fine_dt"] / v.parameters["base_substeps"]
        kept = abs(n1_step - 0.01) < 1e-12 and len(out) != 0  # one variant at 0.01 s dropped as well (6 of 7 kept)
        out.append(Outcome(id=v.id, parameters=v.parameters, kept=kept,
                           failed=[] if kept else ["substeps_reduce_proxy"]))
    return out


def test_the_survey_counts_kept_and_drops_and_proposes_the_n1_step_rule_that_loses_no_kept_variant():
    measured = outcomes()
    finer = [o for o in measured if o.parameters["fine_dt"] / o.parameters["base_substeps"] < 0.01 - 1e-12]
    assert finer and all(not o.kept for o in finer)  # the sample holds the pattern this test is about
    s = survey(measured, SPACE.parameters, min_support=1)
    kept = sum(o.kept for o in measured)
    assert (s.measured, s.kept) == (16, kept) and s.drops_by_condition == {"substeps_reduce_proxy": 16 - kept}
    tallies = s.by_value["N1_internal_dt"]
    assert tallies["0.01"].kept == kept and all(t.kept == 0 for v, t in tallies.items() if v != "0.01")
    (best,) = [p for p in s.proposals if p.name == "N1_internal_dt_as_measured"]
    assert best.rule == "close(fine_dt / base_substeps, 0.01)" and best.loses == 0
    assert best.removes == len(finer)
    assert best.kept_fraction_after == kept / (16 - len(finer))
    text = "\n".join(report_lines(s, "v1"))
    assert f"kept {kept} of 16" in text and "N1_internal_dt" in text and best.rule in text
    # By default a value measured once is not excluded on its own (the sample holds one variant at 0.0025 s): the
    # rule then names what it excludes.
    once = {v for v, t in tallies.items() if t.measured == 1 and not t.kept}
    assert once, tallies
    (default,) = [p for p in survey(measured, SPACE.parameters).proposals if p.name == "N1_internal_dt_as_measured"]
    assert default.rule.startswith("not close(fine_dt / base_substeps, ") and all(v not in default.rule for v in once)
    assert default.removes == len(finer) - sum(tallies[v].dropped for v in once)


def test_only_quantities_that_change_a_checked_case_are_proposed():
    """A drop of the lab check cannot come from the extension (N5 is not a check case): the survey says so."""
    from rubric.cases import CHECK_CASES
    from rubric.variants.survey import checked_quantities

    checked = checked_quantities(SPACE.choices(), CHECK_CASES)
    assert {"extension_dt", "extension_substeps", "N5_internal_dt"} & checked == set()
    assert {"fine_dt", "base_substeps", "cube_size", "table_friction", "N1_internal_dt"} <= checked
    measured = outcomes()
    # every variant with 8 extension substeps dropped (whatever else): proposed without `checked`, not with it
    rigged = [o.model_copy(update={"kept": False}) if o.parameters["extension_substeps"] == 8 else o for o in measured]
    assert any(p.name.startswith("extension_substeps") or p.name.startswith("N5_")
               for p in survey(rigged, SPACE.parameters).proposals)
    assert not any(p.name.startswith(("extension_", "N5_"))
                   for p in survey(rigged, SPACE.parameters, checked=checked).proposals)


def test_no_proposal_when_no_value_of_any_quantity_holds_only_drops():
    measured = [o.model_copy(update={"kept": i % 2 == 0}) for i, o in enumerate(outcomes())]
    s = survey(measured[:2], SPACE.parameters, min_support=1)
    # two variants, one kept: a quantity on which they differ separates them, one on which they agree does not
    assert all(p.loses == 0 and p.removes == 1 for p in s.proposals)
    same = survey([measured[0], measured[0].model_copy(update={"kept": False, "id": "x"})], SPACE.parameters)
    assert same.proposals == [] and "no constraint on one quantity" in "\n".join(report_lines(same, "t"))
