"""Rubric governance: used versions are immutable, tolerance changes need a new reviewed version, regrades preview."""

from __future__ import annotations

import copy
import datetime as dt
import json

import pytest
import yaml
from pydantic import ValidationError

from rubric import (
    RubricGovernanceError,
    grade_sheet,
    lane_metrics,
    load_rubric,
    parse_sheet,
    publish_version,
    report_changes,
)
from rubric import rubrics
from rubric.governance import rubric_changes
from rubric.rubrics import parse_rubric, rubric_versions
from tests.factories import reference_sheet, sheet_results


def edited(rubric, *, version=None, review=None, **tolerances):
    """A validated copy of `rubric` with some tolerance fields replaced (tolerances: name={field: value})."""
    data = rubric.model_dump(mode="json")
    for name, fields in tolerances.items():
        data["tolerances"][name].update(fields)
    if version:
        data["version"] = version
    if review:
        data["review"].update(review)
    return parse_rubric(data)


NEW_REVIEW = {"reviewer": "second reviewer", "review_date": "2026-12-01"}  # not a clock time: a review record


def test_load_rubric_latest_and_by_version():
    versions = rubric_versions("L03")
    assert len(versions) >= 2, "the archived v1 and at least one current version ship"
    by_version = {v: load_rubric("L03", v) for v in versions}
    assert {r.version for r in by_version.values()} == set(versions)
    assert len({r.content_hash for r in by_version.values()}) == len(versions)  # each version its own content
    latest = load_rubric()
    assert latest.lesson == "L03" and latest.version == versions[-1] != "1"
    assert latest.content_hash == by_version[versions[-1]].content_hash != by_version["1"].content_hash
    with pytest.raises(LookupError, match="no rubric version '9'"):
        load_rubric("L03", "9")
    with pytest.raises(LookupError, match="no rubric files for lesson 'L99'"):
        load_rubric("L99")


def test_latest_means_the_highest_version_number_not_the_last_file_name(tmp_path, monkeypatch):
    current = load_rubric("L03")
    for version in ("2", "10", "9"):
        data = current.model_dump(mode="json") | {"version": version}
        (tmp_path / f"L03-v{version}.yaml").write_text(yaml.safe_dump(data))
    monkeypatch.setattr(rubrics, "lesson_folder", lambda lesson: tmp_path)
    assert rubric_versions("L03") == ["2", "9", "10"]
    assert load_rubric("L03").version == "10"  # as text, "9" > "2" > "10"


def test_every_tolerance_carries_its_review_record():
    for name, tol in load_rubric("L03").tolerances.items():
        assert tol.unit and len(tol.rationale) >= 20 and tol.reviewer, name
        assert isinstance(tol.review_date, dt.date)


def test_a_tolerance_without_rationale_is_refused():
    data = load_rubric("L03").model_dump(mode="json")
    del data["tolerances"]["proxy_resolution"]["rationale"]
    with pytest.raises(ValidationError, match="tolerances.proxy_resolution.rationale"):
        parse_rubric(data)


def test_content_hash_is_canonical_and_tracks_content():
    rubric = load_rubric("L03")
    reordered = parse_rubric(json.loads(json.dumps(rubric.model_dump(mode="json"), sort_keys=True)))
    assert reordered.content_hash == rubric.content_hash
    assert edited(rubric, proxy_resolution={"value": 0.001}).content_hash != rubric.content_hash


def test_editing_a_tolerance_of_a_used_version_is_refused():
    v1 = load_rubric("L03", "1")
    changed = edited(v1, high_lane_unchanged={"value": 0.05, **NEW_REVIEW})
    with pytest.raises(RubricGovernanceError, match="version 1 is used by existing grades and is immutable") as info:
        publish_version(changed, [v1], used_versions={"1"})
    assert "tolerances.high_lane_unchanged: 0.01 m -> 0.05 m" in str(info.value)


def test_republishing_identical_content_is_a_no_op_and_an_unused_draft_may_change():
    v1 = load_rubric("L03", "1")
    assert publish_version(copy.deepcopy(v1), [v1], used_versions={"1"}) is v1
    draft = edited(v1, high_lane_unchanged={"value": 0.05})
    assert publish_version(draft, [v1], used_versions=set()) is draft


def test_a_new_version_needs_its_own_review_records():
    v1 = load_rubric("L03", "1")
    same_review = edited(v1, version="2", high_lane_unchanged={"value": 0.005, **NEW_REVIEW})
    with pytest.raises(RubricGovernanceError, match="repeats the review record of version 1"):
        publish_version(same_review, [v1], used_versions={"1"})
    unreviewed = edited(v1, version="2", review=NEW_REVIEW, high_lane_unchanged={"value": 0.005})
    with pytest.raises(RubricGovernanceError, match="tolerances.high_lane_unchanged: changed 0.01 m -> 0.005 m without a new review"):
        publish_version(unreviewed, [v1], used_versions={"1"})
    v2 = edited(v1, version="2", review=NEW_REVIEW, high_lane_unchanged={"value": 0.005, **NEW_REVIEW})
    assert publish_version(v2, [v1], used_versions={"1"}) is v2
    assert rubric_changes(v1, v2)[0] == "tolerances.high_lane_unchanged: 0.01 m -> 0.005 m"


def _results(measured):
    """The reference sheet's configs equal friction-table-0.30 and N5 up to their names: reuse those measurements."""
    return sheet_results(measured), parse_sheet(reference_sheet())


def test_regrade_under_a_new_version_previews_the_per_student_diff_and_keeps_old_grades(measured):
    results, reference = _results(measured)
    misconceived = reference.model_copy(update={"student": "bob", "answers": reference.answers.model_copy(
        update={"H3": reference.answers.H3.model_copy(update={"high": "farther"})})})
    v2 = load_rubric("L03", "2")
    old = {s.student: grade_sheet(s, results, v2) for s in (reference, misconceived)}
    before = {k: r.model_dump() for k, r in old.items()}

    # A reviewer tightens "nearly unchanged" below the high lane's measured change: the control becomes decisive.
    base, mod = measured["friction-baseline"], measured["friction-table-0.30"]
    delta = abs(lane_metrics(mod.spec, mod.arrays, "high").stop.distance
                - lane_metrics(base.spec, base.arrays, "high").stop.distance)
    assert delta > 0, "the regrade scenario needs a non-zero measured change of the high lane"
    v3 = publish_version(edited(v2, version="3", review=NEW_REVIEW,
                                high_lane_unchanged={"value": delta / 2, **NEW_REVIEW}), [v2], used_versions={"2"})
    new = {s.student: grade_sheet(s, results, v3) for s in (reference, misconceived)}
    preview = report_changes(old, new)

    rows = {row.student: row for row in preview.rows}
    assert set(rows) == {"reference", "bob"}
    ref, bob = rows["reference"], rows["bob"]
    assert (ref.old_version, ref.new_version) == ("2", "3")
    assert ref.old_score == old["reference"].total and ref.new_score == new["reference"].total
    assert {c.id for c in ref.changed_items} == {"B3", "H3"}  # "unchanged" no longer holds at the tighter margin
    assert ref.delta == -(v2.item("B3").points + v2.item("H3").points)
    assert {c.id for c in bob.changed_items} == {"B3", "H3"}
    h3 = next(c for c in bob.changed_items if c.id == "H3")
    assert (h3.old_verdict, h3.new_verdict) == ("no_credit", "credit")
    assert {r.student for r in preview.changed} == {"reference", "bob"}
    # Previewing never rewrites the old grades.
    assert {k: r.model_dump() for k, r in old.items()} == before
    assert all(r.rubric_version == "2" for r in old.values())


def test_grading_under_the_archived_v1_is_refused_but_v1_still_loads(measured):
    results, reference = _results(measured)
    v1 = load_rubric("L03", "1")
    assert v1.version == "1" and v1.items  # grades stored under v1 stay readable
    with pytest.raises(ValueError, match="rubric L03 v1 is archived"):
        grade_sheet(reference, results, v1)


def test_preview_lists_students_on_one_side_only(measured):
    results, reference = _results(measured)
    report = grade_sheet(reference, results, load_rubric("L03"))
    preview = report_changes({"reference": report}, {})
    row = preview.rows[0]
    assert (row.old_score, row.new_score, row.delta) == (report.total, None, None)
    assert len(row.changed_items) == len(report.items)
