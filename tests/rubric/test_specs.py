"""Case-spec validation: every bad-input class is refused with an error naming the field and the rule."""

import json

import pytest
from pydantic import ValidationError

from rubric import BASELINE_CASES, describe_errors, field_changes, get_case, parse_case


def errors_for(**fields) -> list[str]:
    data = {"kind": "contact", "name": "x", **fields}
    with pytest.raises(ValidationError) as info:
        parse_case(data)
    return describe_errors(info.value)


@pytest.mark.parametrize(
    ("fields", "field", "rule"),
    [
        ({"dt": 0.0}, "dt", "greater than 0"),
        ({"dt": -0.01}, "dt", "greater than 0"),
        ({"substeps": 0}, "substeps", "greater than or equal to 1"),
        ({"substeps": 1.5}, "substeps", "valid integer"),
        ({"substeps": "2"}, "substeps", "valid integer"),
        ({"duration": 1.505}, "duration", "not an integer number of outer steps"),
        ({"dt": float("nan")}, "dt", "finite"),
        ({"duration": float("inf")}, "duration", "finite"),
        ({"gravity": [0.0, 0.0, float("-inf")]}, "gravity.2", "finite"),
        ({"cube": {"friction": -0.2}}, "cube.friction", "greater than or equal to 0.01"),
        ({"table": {"friction": float("nan")}}, "table.friction", "finite"),
        ({"cube": {"rho": -500.0}}, "cube.rho", "greater than 0"),
        ({"cube": {"rho": 0.0}}, "cube.rho", "greater than 0"),
        ({"cube": {"pos": [0.35, 0.0, 0.72]}}, "cube.pos", "starts inside the table"),
        ({"dt": 0.0001, "duration": 30.0}, "duration", "exceeds the cap"),
        ({"dt": 0.005, "substeps": 64, "duration": 30.0}, "duration", "internal updates exceeds the cap"),
        ({"cube": {"size": 1e6}}, "cube.size", "less than or equal to 10"),
        ({"substep": 2}, "substep", "Extra inputs are not permitted"),
        ({"substep_dt": 0.005}, "substep_dt", "Extra inputs are not permitted"),
        ({"cube": {"colour": [1, 0, 0]}}, "cube.colour", "Extra inputs are not permitted"),
        ({"backend": "gpu"}, "backend", "'cpu', 'rocm' or 'cuda'"),
        ({"precision": "16"}, "precision", "'32' or '64'"),
        ({"tail_window": 2.0}, "tail_window", "longer than duration"),
    ],
)
def test_bad_contact_input_names_field_and_rule(fields, field, rule):
    errors = errors_for(**fields)
    assert any(e.startswith(f"{field}:") and rule in e for e in errors), errors


@pytest.mark.parametrize(
    ("fields", "field", "rule"),
    [
        ({"lanes": [{"name": "low", "friction": 0.1, "y": 0.0, "color": [1, 0, 0], "rho": 3}]}, "lanes.0.rho", "Extra"),
        ({"start_x": -0.5}, "lanes.0", "does not start fully on the table"),
        ({"settle_steps": -1}, "settle_steps", "greater than or equal to 0"),
        ({"hold": 0.0}, "hold", "greater than 0"),
        ({"duration": 2.005}, "duration", "not an integer number of outer steps"),
        ({"initial_speed": float("nan")}, "initial_speed", "finite"),
    ],
)
def test_bad_friction_input_names_field_and_rule(fields, field, rule):
    with pytest.raises(ValidationError) as info:
        parse_case({"kind": "friction", "name": "f", **fields})
    errors = describe_errors(info.value)
    assert any(e.startswith(f"{field}:") and rule in e for e in errors), errors


def test_unknown_kind_is_refused():
    with pytest.raises(ValidationError) as info:
        parse_case({"kind": "pendulum", "name": "x"})
    assert "'contact', 'friction'" in describe_errors(info.value)[0]


def test_derived_quantities_follow_the_lesson_table():
    expected = {"N1": (0.010, 150, 150), "N2": (0.005, 150, 300), "N3": (0.020, 75, 75), "N4": (0.010, 75, 150)}
    for name, (substep_dt, samples, updates) in expected.items():
        spec = get_case(name)
        assert spec.substep_dt == pytest.approx(substep_dt)
        assert (spec.sample_count, spec.internal_updates) == (samples, updates)


def test_float_step_ratio_within_representation_error_is_accepted():
    # 1.5 / 0.01 = 150.00000000000003 in binary floating point: an integer step count, not a validation error.
    assert parse_case({"kind": "contact", "name": "x", "dt": 0.01, "duration": 1.5}).n_steps == 150


def test_shown_spec_round_trips_and_baseline_differs_by_one_factor():
    for spec in BASELINE_CASES.values():
        assert parse_case(json.loads(spec.model_dump_json(exclude_computed_fields=True))) == spec
    def changed(a, b):
        return [c.field for c in field_changes(get_case(a), get_case(b))]

    assert changed("N1", "N2") == ["substeps"]
    assert changed("N3", "N4") == ["substeps"]
    assert changed("friction-baseline", "friction-table-0.30") == ["table.friction"]
    assert changed("N1", "N3") == ["dt"]
    change = field_changes(get_case("friction-baseline"), get_case("friction-table-0.30"))[0]
    assert (change.baseline, change.config) == (0.5, 0.3)


def test_step_count_rule_applies_to_the_default_duration():
    # Only dt given: 1.5 s / 0.013 s is not an integer number of steps, even though duration was not written.
    errors = errors_for(dt=0.013)
    assert any(e.startswith("duration:") and "not an integer number of outer steps" in e for e in errors), errors


def test_the_physics_key_is_what_a_case_integrates_however_it_is_sampled_labelled_or_run():
    """rubric.specs.physics_key (issue 44): runs of one key measure the same trajectories at every shared time."""
    from rubric.cases import BASELINE_CASES as cases
    from rubric.specs import physics_key

    def key(case, **change):
        return physics_key(cases[case].model_copy(update=change))

    assert key("N1") == key("N4") and key("N1") != key("N2") != key("N3")  # internal step 0.01 / 0.005 / 0.02
    assert key("N5", dt=0.02, substeps=4) == key("N2")  # an extension integrating at N2's step
    assert key("N2", name="mine", precision="64", backend="gpu", seed=7, duration=0.5, render=True) == key("N2")
    assert key("N2", cube=cases["N2"].cube.model_copy(update={"color": (0.0, 0.0, 1.0)})) == key("N2")
    assert key("N2", cube=cases["N2"].cube.model_copy(update={"rho": 800.0})) != key("N2")
    # below single precision's resolution the engine integrates the same (hostile pass 3): the same physics
    assert key("N5", dt=0.0100000000001, substeps=2) == key("N2")
    table = cases["friction-baseline"].table
    assert key("friction-baseline", table=table.model_copy(update={"friction": 0.5000000001})) == key("friction-baseline")
    assert key("friction-baseline", table=table.model_copy(update={"friction": 0.51})) != key("friction-baseline")
    assert key("friction-baseline") == key("friction-baseline-colors-swapped") != key("friction-table-0.30")
    # settling is part of the physics: as many internal updates of settling at the same internal step are the same
    base = cases["friction-baseline"]
    assert key("friction-baseline", substeps=base.substeps * 2, dt=base.dt * 2,
               settle_steps=base.settle_steps // 2) == key("friction-baseline")
    assert key("friction-baseline", settle_steps=base.settle_steps + 1) != key("friction-baseline")
