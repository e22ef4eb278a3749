"""The pool draw: deterministic from (space, seed, k) in any process, every variant inside its constraints and building
valid cases, and every refused draw reported with its reason rather than retried for ever."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from rubric.cases import BASELINE_CASES, COLOR_SWAP
from rubric.specs import field_changes, parse_case
from rubric.variants import (
    VariantPoolError,
    draw_pool,
    load_variant_space,
    parse_variant_space,
    shipped_parameters,
    shipped_variant,
    variant_cases,
)
from tests.factories import ROOT

SPACE = load_variant_space("L03", "1")  # the mechanics on version 1, whose pools are stored (issue 47 added v2)
SCRIPT = ("import json, sys; from rubric.variants import draw_pool, load_variant_space; "
          "print(draw_pool(load_variant_space('L03', '1'), int(sys.argv[1]), int(sys.argv[2])).model_dump_json())")


def pool_json(seed: int, k: int) -> str:
    return draw_pool(SPACE, seed, k).model_dump_json()


def test_the_same_seed_gives_the_same_pool_and_another_seed_another():
    assert pool_json(7, 16) == pool_json(7, 16)
    a, b = draw_pool(SPACE, 7, 16), draw_pool(SPACE, 8, 16)
    assert [v.id for v in a.variants] == [f"v7-{n}" for n in range(1, 17)]
    assert [v.digest for v in a.variants] != [v.digest for v in b.variants]
    # Draws are sequential: a larger pool from the same seed extends the smaller one.
    assert draw_pool(SPACE, 7, 20).variants[:16] == a.variants


@pytest.mark.parametrize("hash_seed", ["0", "12345"])
def test_another_process_with_other_hash_randomisation_draws_the_same_pool(hash_seed):
    env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONHASHSEED": hash_seed}
    out = subprocess.run([sys.executable, "-c", SCRIPT, "2026", "16"], cwd=ROOT, env=env, capture_output=True,
                         text=True, timeout=120, check=True).stdout
    assert json.loads(out) == json.loads(pool_json(2026, 16))


@pytest.mark.parametrize("seed", range(6))
def test_every_drawn_variant_keeps_the_constraints_and_builds_valid_cases(seed):
    pool = draw_pool(SPACE, seed, 16)
    assert len(pool.variants) == 16 and len({v.digest for v in pool.variants}) == 16
    shipped = shipped_parameters()
    for v in pool.variants:
        assert SPACE.violations(v.parameters) == [], v.id
        assert v.parameters != shipped and set(v.parameters) == set(shipped)
        assert (v.space_version, v.space_hash) == ("1", SPACE.content_hash)
        for name in v.parameters:
            if name in SPACE.parameters:
                assert v.parameters[name] in SPACE.choices()[name]
            else:
                assert v.parameters[name] == shipped[name]
        cases = v.cases()
        assert list(cases) == list(BASELINE_CASES)
        for name, spec in cases.items():
            # What the worker receives: the spec's JSON through the same validation a submitted config passes.
            again = parse_case(json.loads(spec.model_dump_json(exclude_computed_fields=True)))
            assert again == spec and again.name == name
        assert_lesson_design(cases)


def assert_lesson_design(cases):
    """The relations between the lesson's cases hold in every variant: one factor per comparison."""
    changed = lambda a, b: [c.field for c in field_changes(cases[a], cases[b]) if not c.visual]  # noqa: E731
    assert changed("N1", "N2") == changed("N3", "N4") == ["substeps"]
    assert changed("N1", "N3") == ["dt"]
    assert cases["N1"].substep_dt == pytest.approx(cases["N4"].substep_dt, rel=1e-9)
    assert cases["N1"].internal_updates == cases["N4"].internal_updates
    assert cases["N1"].sample_count != cases["N4"].sample_count
    assert len({cases[n].duration for n in ("N1", "N2", "N3", "N4", "N5")}) == 1
    assert changed("friction-baseline", "friction-table-0.30") == ["table.friction"]
    assert changed("friction-baseline", COLOR_SWAP) == []
    assert field_changes(cases["friction-baseline"], cases[COLOR_SWAP])  # the colours did swap
    low, high = (lane.friction for lane in cases["friction-baseline"].lanes)
    assert low < cases["friction-table-0.30"].table.friction < cases["friction-baseline"].table.friction < high


def test_the_shipped_parameters_build_exactly_the_lessons_cases():
    assert variant_cases(None) == BASELINE_CASES
    built = variant_cases(shipped_parameters())
    assert all(built[name] == BASELINE_CASES[name] for name in BASELINE_CASES)
    assert shipped_variant().cases() == BASELINE_CASES and shipped_variant().shipped
    with pytest.raises(KeyError, match="unknown variant parameters \\['drop_height'\\]"):
        variant_cases({"drop_height": 0.9})


def test_a_draw_that_builds_an_invalid_case_is_reported_with_the_case_and_field():
    data = SPACE.model_dump(mode="json")
    del data["constraints"]["steps_integral"]  # without it, 1.2 s at dt 0.03 is drawn: not whole steps
    pool = draw_pool(parse_variant_space(data), 3, 16)
    invalid = [reason for r in pool.rejected for reason in r.reasons if reason.startswith("invalid case")]
    assert invalid and all(reason.startswith("invalid case: N") for reason in invalid)
    assert any(".duration: duration / dt = " in reason and "is not an integer number of outer steps" in reason
               for reason in invalid), invalid
    assert pool.reasons()["invalid case"] == len(invalid)


def test_an_impossible_pool_raises_with_the_reasons_instead_of_looping():
    data = SPACE.model_dump(mode="json")
    data["parameters"] = {"cube_rho": data["parameters"]["cube_rho"]}
    data["constraints"] = {}
    with pytest.raises(VariantPoolError, match="holds 4 combinations of its parameters, fewer than the 5"):
        draw_pool(parse_variant_space(data), 1, 5)
    # Four densities, one of them the lesson's own: three variants at most, refused draws named, bounded attempts.
    with pytest.raises(VariantPoolError) as info:
        draw_pool(parse_variant_space(data), 1, 4, max_attempts=60)
    pool = info.value.pool
    assert len(pool.variants) == 3 and len(pool.rejected) == 60 - 3
    assert set(pool.reasons()) == {"shipped", "repeat"}
    assert "only 3 of 4 variants after 60 draws; draws were refused by" in str(info.value)


def test_variants_differ_from_each_other_in_as_many_parameters_as_asked():
    pool = draw_pool(SPACE, 11, 8, min_differences=4)
    params = [v.parameters for v in pool.variants] + [shipped_parameters()]
    for i, a in enumerate(params):
        for b in params[i + 1:]:
            assert sum(a[n] != b[n] for n in a) >= 4


def test_a_stored_variant_reads_back_typed_as_the_lesson_types_its_parameters():
    from pydantic import ValidationError

    from rubric.variants import Variant

    pool = draw_pool(SPACE, 5, 3)
    for v in pool.variants:
        again = Variant.model_validate_json(v.model_dump_json())
        assert again == v and again.digest == v.digest
    loose = Variant(id="v5-9", parameters=shipped_parameters() | {"cube_rho": 800, "more_substeps": 3.0})
    assert loose.parameters["cube_rho"] == 800.0 and type(loose.parameters["cube_rho"]) is float
    assert type(loose.parameters["more_substeps"]) is int
    assert loose.digest == Variant(id="v5-9", parameters=shipped_parameters() | {"cube_rho": 800.0,
                                                                                 "more_substeps": 3}).digest
    with pytest.raises(ValidationError, match="more_substeps takes whole numbers, got 2.5"):
        Variant(id="v5-9", parameters=shipped_parameters() | {"more_substeps": 2.5})
    with pytest.raises(ValidationError, match=r"unknown parameters \['drop_height'\], missing \['cube_start_z'\]"):
        params = shipped_parameters()
        params["drop_height"] = params.pop("cube_start_z")
        Variant(id="v5-9", parameters=params)
