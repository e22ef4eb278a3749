"""rubric.tolerance_review: which quantity each tolerance judges, and flagging a tolerance narrower than a measured
cross-backend or cross-precision difference (pure: stored metrics and audit comparisons as plain data)."""

from __future__ import annotations

import re
from pathlib import Path

from rubric.rubrics import load_rubric
from rubric.tolerance_review import (JUDGED, StoredValue, comparison_differences, review_rubric, spreads,
                                     stored_values, variant_axes)

RUBRIC_DIR = Path(__file__).resolve().parents[2] / "rubric"


def _contact_comparison(proxy_left: float, proxy_right: float, dz: float) -> dict:
    """What rubric.discrepancy stores for a contact case (only the fields the review reads)."""
    return {"arrays": [{"name": "z", "unit": "m", "shared_samples": 150, "max_abs": dz},
                       {"name": "vz", "unit": "m/s", "shared_samples": 150, "max_abs": 1e-6}],
            "metrics": [{"name": "penetration_proxy", "unit": "m", "left": proxy_left, "right": proxy_right},
                        {"name": "passed_through", "unit": "yes/no", "left": False, "right": False},
                        {"name": "first_contact_time", "unit": "s", "left": None, "right": None}]}


def test_every_tolerance_the_scoring_and_the_lab_check_read_is_mapped_to_a_quantity():
    read = set()
    for path in [*(RUBRIC_DIR / "scoring").glob("*.py"), RUBRIC_DIR / "check.py"]:
        text = path.read_text()
        read |= set(re.findall(r'tol\("([a-z0-9_]+)"\)', text))
        read |= set(re.findall(r'tol(?:erances)?\["([a-z0-9_]+)"\]', text))
    shipped = set(load_rubric("L03", "2").tolerances)
    assert read and read <= set(JUDGED), sorted(read - set(JUDGED))
    assert shipped <= set(JUDGED), sorted(shipped - set(JUDGED))
    assert set(JUDGED) <= shipped  # no mapping of a tolerance nobody declares


def test_a_precision_difference_wider_than_a_tolerance_is_flagged_with_its_entry():
    rubric = load_rubric("L03", "2")
    differences = comparison_differences(41, "N1", "cpu/32/warm", "cpu/64/warm", "contact", [],
                                         _contact_comparison(0.01319, 0.01399, dz=0.0008))
    reviews = {r.name: r for r in review_rubric(rubric, [], differences)}
    proxy = reviews["proxy_resolution"]
    assert proxy.flagged and proxy.flag_entries == [41] and proxy.items == ["A2", "X2", "X3"]
    assert "audit entry 41 (N1, cpu/32/warm vs cpu/64/warm)" in proxy.reasons[0] and "> 0.0005 m" in proxy.reasons[0]
    assert abs(proxy.largest_audit.abs_diff - 0.0008) < 1e-12
    assert reviews["n1_n4_max_dz"].flagged  # the z array differs by 0.8 mm > 0.1 mm
    assert not reviews["n1_n4_max_dvz"].flagged and reviews["n1_n4_max_dvz"].audit  # 1e-6 m/s is inside 0.05
    assert not reviews["stop_distance_resolution"].flagged and not reviews["stop_distance_resolution"].audit
    assert [r.name for r in review_rubric(rubric, [], differences)][:2] == ["proxy_resolution", "n1_n4_max_dz"]


def test_a_difference_inside_the_tolerance_or_between_modes_only_is_not_flagged():
    rubric = load_rubric("L03", "2")
    inside = comparison_differences(1, "N1", "cpu/32/warm", "cuda/32/warm", "contact", [],
                                    _contact_comparison(0.01319, 0.01329, dz=0.00001))
    modes = comparison_differences(2, "N1", "cpu/32/warm", "cpu/32/isolated", "contact", [],
                                   _contact_comparison(0.01319, 0.01399, dz=0.0008))
    reviews = {r.name: r for r in review_rubric(rubric, [], inside + modes)}
    assert not reviews["proxy_resolution"].flagged
    assert reviews["proxy_resolution"].largest_audit.entry_id == 2  # shown, largest first, but a mode is no flag
    assert variant_axes("cpu/32/warm", "cuda/64/warm") == ["backend", "precision"]


def test_a_lane_stopped_on_one_backend_only_flags_the_stop_distance_tolerances():
    comparison = {"arrays": [{"name": "low_x", "unit": "m", "shared_samples": 100, "max_abs": 0.001}],
                  "metrics": [{"name": "low.stop_distance", "unit": "m", "left": 0.21, "right": None},
                              {"name": "high.stop_distance", "unit": "m", "left": 0.05, "right": 0.0501},
                              {"name": "low.pair_friction", "unit": "dimensionless", "left": 0.5, "right": 0.5}]}
    differences = comparison_differences(7, "friction-baseline", "cpu/32/warm", "cuda/32/warm", "friction",
                                         ["low", "high"], comparison)
    assert {d.quantity for d in differences} == {"lane.x", "lane.stop_distance", "lane.pair_friction"}
    reviews = {r.name: r for r in review_rubric(load_rubric("L03", "2"), [], differences)}
    for name in ("stop_distance_resolution", "high_lane_unchanged", "reported_stop_distance"):
        assert reviews[name].flagged and "exists on one side only" in reviews[name].reasons[0], name
    assert not reviews["pair_friction_abs"].flagged


def test_stored_values_and_their_spread_per_case_spec():
    contact = {"kind": "contact", "penetration_proxy": 0.0132, "separation_samples": 3, "passed_through": False,
               "max_upward_velocity_after_contact": None}
    friction = {"kind": "friction", "lanes": {"low": {"stop": {"distance": 0.2}, "pair_friction": 0.5},
                                              "high": {"stop": {"distance": None}, "pair_friction": 0.8}}}
    assert stored_values(contact, "contact.penetration_proxy") == [(None, 0.0132)]
    assert stored_values(contact, "contact.max_upward_velocity_after_contact") == []
    assert stored_values(contact, "contact.z") == [] and stored_values(friction, "contact.penetration_proxy") == []
    assert stored_values(friction, "lane.stop_distance") == [("low", 0.2)]
    assert stored_values(friction, "lane.pair_friction") == [("high", 0.8), ("low", 0.5)]
    values = [StoredValue(case="N1", spec_key="a", case_run_id=i, variant=v, quantity="contact.penetration_proxy",
                          value=x) for i, v, x in ((1, "cpu/32/warm", 0.0132), (2, "cpu/64/warm", 0.0135))]
    values.append(StoredValue(case="N2", spec_key="b", case_run_id=3, variant="cpu/32/warm",
                              quantity="contact.penetration_proxy", value=0.0078))
    widest, other = spreads(values)
    assert (widest.case, widest.n, widest.case_run_ids, widest.variants) == ("N1", 2, [1, 2], ["cpu/32/warm",
                                                                                               "cpu/64/warm"])
    assert abs(widest.spread - 0.0003) < 1e-12 and other.spread == 0.0
