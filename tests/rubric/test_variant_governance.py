"""A variant space is governed as tolerances are: a used version is immutable, and a changed parameter or constraint
needs a new version with a fresh review of what changed."""

from __future__ import annotations

import pytest

from rubric import RubricGovernanceError, publish_variant_space
from rubric.governance import variant_space_changes
from rubric.variants import load_variant_space, parse_variant_space

V1 = load_variant_space("L03", "1")
NEW_REVIEW = {"reviewer": "second reviewer", "review_date": "2026-12-01"}  # not a clock time: a review record


def edited(*, version="2", review=NEW_REVIEW, **sections):
    """A copy of v1 as another version; sections: parameters={name: {field: value}} or constraints=..."""
    data = V1.model_dump(mode="json") | {"version": version}
    data["review"] = data["review"] | (review or {})
    for section, entries in sections.items():
        for name, fields in entries.items():
            data[section][name] = data[section].get(name, {}) | fields
    return parse_variant_space(data)


def test_republishing_identical_content_is_a_no_op_and_a_used_version_is_immutable():
    assert publish_variant_space(V1, [V1], {"1"}) is V1
    changed = edited(version="1", review=None, parameters={"launch_speed": {"choices": [1.8, 2.2]}})
    with pytest.raises(RubricGovernanceError, match=r"variant space L03 version 1 is used by a variant pool and is "
                                                    r"immutable .*parameters.launch_speed: .*publish them as a new"):
        publish_variant_space(changed, [V1], {"1"})
    assert publish_variant_space(changed, [V1], set()) is changed  # an unused draft may still be replaced


def test_a_new_version_needs_its_own_review_and_a_fresh_review_of_each_change():
    with pytest.raises(RubricGovernanceError, match="repeats the review record of version 1"):
        publish_variant_space(edited(review={}), [V1], {"1"})
    widened = {"range": {"min": 0.35, "max": 0.60, "step": 0.05}}
    with pytest.raises(RubricGovernanceError, match=r"parameters.table_friction: changed .*0.4.* -> .*0.35.* without a "
                                                    r"new review \(reviewer and date still variant space author"):
        publish_variant_space(edited(parameters={"table_friction": widened}), [V1], {"1"})
    loosened = {"rule": "high_lane_friction - table_friction >= 0.1"}
    with pytest.raises(RubricGovernanceError, match="constraints.baseline_lanes_resolvable: changed"):
        publish_variant_space(edited(constraints={"baseline_lanes_resolvable": loosened}), [V1], {"1"})
    backdated = {"reviewer": "second reviewer", "review_date": "2026-11-01"}  # not a clock time: a review record
    with pytest.raises(RubricGovernanceError, match="parameters.table_friction: changed"):
        publish_variant_space(edited(parameters={"table_friction": widened | backdated}), [V1], {"1"})
    reviewed = edited(parameters={"table_friction": widened | NEW_REVIEW},
                      constraints={"baseline_lanes_resolvable": loosened | NEW_REVIEW})
    assert publish_variant_space(reviewed, [V1], {"1"}) is reviewed
    assert variant_space_changes(V1, reviewed)[:2] == [
        "parameters.table_friction: {'unit': '1', 'range': {'min': 0.4, 'max': 0.6, 'step': 0.05}} -> "
        "{'unit': '1', 'range': {'min': 0.35, 'max': 0.6, 'step': 0.05}}",
        "constraints.baseline_lanes_resolvable: {'rule': 'high_lane_friction - table_friction >= 0.2'} -> "
        "{'rule': 'high_lane_friction - table_friction >= 0.1'}",
    ]
    # A rationale reworded is not a change of what varies: no fresh review needed.
    reworded = edited(parameters={"cube_rho": {"rationale": "Density changes mass and inertia only, nothing else."}})
    assert publish_variant_space(reworded, [V1], {"1"}) is reworded


def test_a_new_parameter_or_constraint_brings_its_own_review():
    added = edited(parameters={"cube_rho": {}}, constraints={"slow_enough": {
        "rule": "launch_speed <= 2.2", "rationale": "keeps every lane's slide well inside the table length",
        **NEW_REVIEW}})
    assert publish_variant_space(added, [V1], {"1"}) is added
    assert "constraints.slow_enough: absent -> {'rule': 'launch_speed <= 2.2'}" in variant_space_changes(V1, added)
