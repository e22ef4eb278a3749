"""Withholding per measurement (issue 31): while an item is withheld, the case runs whose measurements decide it are
withheld with it on every surface a student reads: other items' evidence (with A2 withheld, X2's
"penetration_proxy N1 ... -> extension ..." answered A2), the series of the report's charts and their captions, the
runs' provenance, metrics and evidence downloads (pages and API), results.json, and the API's grade and case runs;
the report says which measurements are hidden until release, and what is withheld stays part of every validator
(a release answers 200 to an ETag taken before it). Which runs decide A2 is read from the staff's grade, as the
rubric's scoring rule recorded it, not written here. Real measured runs (the session's Genesis cases), the real app
in-process on SQLite, the worker's own grading functions."""

from __future__ import annotations

import html

from tests.grader.services.setup.test_assignments import create
from tests.grader.services.submissions.test_integrity_withholding import free_graded, grade_of

COMMENT = "A2's direction is read from both pairs; the answer given names only one."


def _a2_withheld(api, measured) -> tuple[int, int, dict]:
    """(assignment id, alice's free graded submission, the staff's items by id) with A2 withheld until release."""
    aid = create(api, part="exercises", item_visibility={"A2": "on_release"}).json()["id"]
    sid = free_graded(api, measured, complete=True)
    staff = grade_of(api, sid, "prof").json()
    return aid, sid, {i["id"]: i for i in staff["items"]}


def _get(api, path, who="alice", **headers):
    return api.client.get(path, headers={**api.as_(who), **headers})


def test_the_runs_deciding_a_withheld_item_are_withheld_on_every_surface_until_release(api, measured):
    aid, sid, staff = _a2_withheld(api, measured)
    deciding = set(staff["A2"]["backends"])  # the runs A2's scoring rule read, as recorded in the grade
    x2 = staff["X2"]
    assert deciding and set(x2["backends"]) & deciding and "penetration_proxy" in x2["measured"], (staff["A2"], x2)
    untouched = [i for i, item in staff.items() if not set(item["backends"]) & deciding and i != "A2"]
    assert "friction-baseline" not in deciding and untouched, untouched
    leaks = [p for p in x2["measured"].split("; ") + staff["A2"]["measured"].split("; ") if p]

    # The API's grade, results.json and the report page: X2 keeps its score and verdict, not its measured values.
    grade = grade_of(api, sid, "alice")
    assert grade.status_code == 200, grade.text
    items = {i["id"]: i for i in grade.json()["items"]}
    assert items["A2"]["verdict"] == "pending"
    mine = items["X2"]
    assert (mine["score"], mine["verdict"]) == (x2["score"], x2["verdict"])
    assert (mine["measured"], mine["evidence"]) == ("", None) and set(mine["evidence_withheld"]) == (
        set(x2["backends"]) & deciding)
    assert all(items[i] == staff[i] for i in untouched)  # an item reading no deciding run is shown whole
    assert set(grade.json()["withheld_measurements"]) == deciding
    results = _get(api, f"/submissions/{sid}/results.json")
    assert results.status_code == 200 and set(results.json()["withheld_measurements"]) == deciding
    page = _get(api, f"/submissions/{sid}")
    assert page.status_code == 200
    text = html.unescape(page.text)
    for where, body in (("grade", grade.text), ("results.json", results.text), ("page", text)):
        assert not [p for p in leaks if p in body], where
    assert 'id="withheld-measurements"' in page.text and all(r in text.split('id="withheld-measurements"')[1]
                                                             .split("</div>")[0] for r in deciding)
    staff_page = html.unescape(_get(api, f"/submissions/{sid}", "prof").text)
    for run in deciding:  # no chart caption or provenance of a deciding run
        caption = f"{run} (dt="
        assert caption in staff_page and caption not in text, run
    assert "Withheld: this run's measurements decide an item not shown to you yet." in text

    # The charts' series, on the page's route and the API's.
    for path in (f"/submissions/{sid}/series.json", f"/v1/submissions/{sid}/series"):
        doc = _get(api, path).json()
        runs = {r["name"]: r for r in doc["runs"]}
        assert set(doc["withheld"]) == deciding, path
        for run in deciding:
            assert runs[run]["status"] == "withheld" and not {"series", "metrics", "data", "lanes"} & set(runs[run])
        assert "series" in runs["friction-baseline"], path
    staff_series = {r["name"]: r for r in _get(api, f"/submissions/{sid}/series.json", "prof").json()["runs"]}
    assert all("series" in staff_series[run] for run in deciding)

    # Evidence downloads (page and API) and the API's case runs.
    for run in deciding:
        for name in ("arrays.npz", "metrics.json", "provenance.json"):
            assert _get(api, f"/submissions/{sid}/case-runs/{run}/{name}").status_code == 409, (run, name)
            refused = _get(api, f"/v1/submissions/{sid}/case-runs/{run}/files/{name}")
            assert refused.status_code == 409 and "withheld" in refused.json()["detail"], refused.text
            assert _get(api, f"/v1/submissions/{sid}/case-runs/{run}/files/{name}", "prof").status_code == 200
    assert _get(api, f"/submissions/{sid}/case-runs/friction-baseline/metrics.json").status_code == 200
    listed = {r["name"]: r for r in _get(api, f"/v1/submissions/{sid}/case-runs").json()}
    assert all(listed[r]["metrics"] is None and listed[r]["provenance"] is None for r in deciding)
    assert listed["friction-baseline"]["metrics"] is not None

    # Released: every surface shows them, and no validator taken before confirms an old answer.
    series_tag = _get(api, f"/submissions/{sid}/series.json").headers["etag"]
    page_tag = page.headers["etag"]
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    series = _get(api, f"/submissions/{sid}/series.json", **{"If-None-Match": series_tag})
    assert series.status_code == 200 and series.json()["withheld"] == {}
    assert all("series" in r for r in series.json()["runs"] if r["name"] in deciding)
    again = _get(api, f"/submissions/{sid}", **{"If-None-Match": page_tag})
    assert again.status_code == 200 and 'id="withheld-measurements"' not in again.text
    after = grade_of(api, sid, "alice").json()
    assert {i["id"]: i for i in after["items"]} == staff and after["withheld_measurements"] == {}
    assert _get(api, f"/v1/submissions/{sid}/case-runs/N1/files/metrics.json").status_code == 200


def test_a_report_whose_withheld_item_carries_an_override_does_not_say_every_score_is_measured(api, measured):
    aid, sid, _ = _a2_withheld(api, measured)
    made = api.client.post(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof"),
                           json={"item_id": "A2", "score": 0, "comment": COMMENT})
    assert made.status_code == 201, made.text
    page = html.unescape(_get(api, f"/submissions/{sid}").text)
    assert "every score is the measured one" not in page and COMMENT not in page
    assert "Whether one was set for a withheld item is shown with that item." in page
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    page = html.unescape(_get(api, f"/submissions/{sid}").text)
    assert 'id="override-A2"' in page and COMMENT in page and "every score is the measured one" not in page


def _item(id_, kind, backends, verdict="credit", **over) -> dict:
    return {"id": id_, "part": "A", "kind": kind, "question": f"question {id_}?", "prediction": "{}", "points": 1.0,
            "score": 1.0, "max_score": 1.0, "verdict": verdict, "expected": f"expected {id_}",
            "measured": f"measured {id_}", "evidence": {f"{id_}_value": 1.5}, "tolerances": {},
            "backends": {b: "cpu" for b in backends}, "feedback": f"feedback {id_}"} | over


def test_which_runs_decide_an_item_follows_its_kind_and_the_runs_its_rule_read():
    """The rule on a stored report: a measured item's runs decide it, a conceptual or config item's do not, a measured
    item naming no run read them all (the engine version of every run), and an unmeasured verdict decides none."""
    from grader.services.submissions.visibility import shown_report, withheld_runs

    runs = ["N1", "N2", "friction-baseline", "sheet.extension"]
    report = {"items": [_item("A2", "measured", ["N1", "N2"]), _item("X2", "measured", ["N1", "sheet.extension"]),
                        _item("A5", "conceptual", ["N1", "N2"]), _item("B2", "measured", ["friction-baseline"]),
                        _item("H6", "measured", []), _item("H5", "config", []),
                        _item("B1", "measured", ["friction-baseline"], verdict="not_measured")],
              "total": 7.0, "max_total": 7.0}
    why = "shown once “Week 1” is released by an instructor"
    assert set(withheld_runs(report, {"A2": why}, runs)) == {"N1", "N2"}
    assert withheld_runs(report, {"A5": why, "H5": why, "B1": why}, runs) == {}
    assert set(withheld_runs(report, {"H6": why}, runs)) == set(runs)
    assert withheld_runs(None, {"A5": why}, runs).keys() == set(runs)  # not graded yet: nothing says which run decides
    shown = {i["id"]: i for i in shown_report(report, {"A2": why}, runs)["items"]}
    assert shown["X2"]["evidence"] is None and shown["X2"]["measured"] == shown["X2"]["expected"] == ""
    assert shown["X2"]["evidence_withheld"] == ["N1"] and shown["X2"]["score"] == 1.0
    assert "measured X2" not in shown["X2"]["feedback"] and "N1 decides A2, " + why in shown["X2"]["feedback"]
    assert shown["A5"]["expected"] == "expected A5" and shown["A5"]["measured"] == ""  # a conceptual answer stays
    assert shown["B2"] == report["items"][3]  # reads no deciding run: shown whole
