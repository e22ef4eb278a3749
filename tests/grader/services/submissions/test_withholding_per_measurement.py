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

from tests.factories import reference_sheet
from tests.grader.services.setup.test_assignments import create, submit
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
    # with them the student's own contact config (issue 44, hostile pass 3): it could be built to measure what they did
    withheld = deciding | {"sheet.extension"}
    x2 = staff["X2"]
    assert deciding and set(x2["backends"]) & deciding and "penetration_proxy" in x2["measured"], (staff["A2"], x2)
    untouched = [i for i, item in staff.items() if not set(item["backends"]) & withheld and i != "A2"]
    assert "friction-baseline" not in deciding and untouched, untouched
    leaks = [p for p in x2["measured"].split("; ") + staff["A2"]["measured"].split("; ") if p]

    # The API's grade, results.json and the report page: X2 reads A2's runs, so its verdict would tell A2's answer
    # (issue 44, hostile pass 6): it waits with A2, saying so, and counts in the points pending.
    grade = grade_of(api, sid, "alice")
    assert grade.status_code == 200, grade.text
    items = {i["id"]: i for i in grade.json()["items"]}
    assert items["A2"]["verdict"] == "pending"
    mine = items["X2"]
    assert (mine["score"], mine["verdict"], mine["measured"], mine["evidence"]) == (None, "pending", "", None)
    assert "its verdict reads the measurements that decide A2" in mine["feedback"], mine
    assert "X2" in grade.json()["pending"], grade.json()["pending"]
    # a friction item reads no contact run: shown whole
    assert all(items[i] == staff[i] for i in ("B1", "B2", "B3", "B4")), [items[i] for i in ("B1", "B2", "B3", "B4")]
    assert all(items[i] == staff[i] or items[i]["verdict"] == "pending" for i in untouched)
    assert set(grade.json()["withheld_measurements"]) == withheld
    results = _get(api, f"/submissions/{sid}/results.json")
    assert results.status_code == 200 and set(results.json()["withheld_measurements"]) == withheld
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
        assert set(doc["withheld"]) == withheld, path
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



def _stops(metrics: dict) -> list[str]:
    """A friction run's lanes' stops as the report page's lane table writes them."""
    return [f"{s['distance']:.3f} m at t={s['time']:.2f} s" for lane in metrics["lanes"].values()
            if (s := lane["stop"])["stopped"]]


def test_a_run_that_measured_the_same_as_a_deciding_one_is_withheld_with_it_whatever_its_name(api, measured):
    """Issue 44, finding 5: with B3 withheld, its deciding runs (friction-baseline, sheet.table_exercise) answered 409
    while the colour-swapped control (the baseline's twin, bit for bit) and the lesson's friction-table-0.30 (the
    sheet's table exercise, measured alike) answered 200 with the same stops and arrays, on every surface."""
    aid = create(api, part="exercises", item_visibility={"B3": "on_release"}).json()["id"]
    sid = free_graded(api, measured, complete=True)
    staff = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}
    deciding = set(staff["B3"]["backends"])
    twins = {"friction-baseline-colors-swapped": "friction-baseline", "friction-table-0.30": "sheet.table_exercise"}
    assert deciding == set(twins.values()), staff["B3"]
    files = {r: _get(api, f"/v1/submissions/{sid}/case-runs/{r}/files/arrays.npz", "prof").content
             for r in (*twins, *twins.values())}
    metrics = {r: _get(api, f"/v1/submissions/{sid}/case-runs/{r}/files/metrics.json", "prof").json()
               for r in (*twins, *twins.values())}
    for twin, run in twins.items():  # what the twins measured is what the deciding runs did, under another name
        assert files[twin] == files[run] and _stops(metrics[twin]) == _stops(metrics[run]), twin
    stops = {s for m in metrics.values() for s in _stops(m)}
    assert stops, metrics

    # Evidence downloads (API and page) answer as for the deciding run: the colour-swapped control says its kind and
    # the deciding run it is withheld with, not that it measured the same (C7's answer: hostile pass 8);
    # friction-table-0.30 is itself what B3 asks of a table exercise (its rule's declared reads).
    why = {"friction-baseline-colors-swapped": "is a friction run, as friction-baseline is, which decides B3",
           "friction-table-0.30": "it decides B3"}
    reasons = grade_of(api, sid, "alice").json()["withheld_measurements"]
    assert reasons and not [r for r in reasons.values() if "measured the same" in r], reasons
    for twin, run in twins.items():
        for name in ("arrays.npz", "metrics.json", "provenance.json"):
            refused = _get(api, f"/v1/submissions/{sid}/case-runs/{twin}/files/{name}")
            assert refused.status_code == 409, (twin, name, refused.status_code)
            assert why[twin] in refused.json()["detail"], refused.text
            assert _get(api, f"/submissions/{sid}/case-runs/{twin}/{name}").status_code == 409, (twin, name)
            assert _get(api, f"/v1/submissions/{sid}/case-runs/{twin}/files/{name}", "prof").status_code == 200
    withheld = deciding | set(twins)
    # The API's case runs, grade and results.json; the charts' series (page and API); the page's lane table.
    listed = {r["name"]: r for r in _get(api, f"/v1/submissions/{sid}/case-runs").json()}
    assert all(listed[r]["metrics"] is None and listed[r]["provenance"] is None for r in withheld)
    assert listed["N1"]["metrics"] is not None
    assert set(grade_of(api, sid, "alice").json()["withheld_measurements"]) == withheld
    assert set(_get(api, f"/submissions/{sid}/results.json").json()["withheld_measurements"]) == withheld
    for path in (f"/submissions/{sid}/series.json", f"/v1/submissions/{sid}/series"):
        doc = _get(api, path)
        runs = {r["name"]: r for r in doc.json()["runs"]}
        assert set(doc.json()["withheld"]) == withheld, path
        assert all(runs[r]["status"] == "withheld" and "series" not in runs[r] for r in withheld), path
        assert "series" in runs["N1"], path
        staff_series = {r["name"]: r for r in _get(api, path, "prof").json()["runs"]}
        assert all("series" in staff_series[r] for r in withheld), path
    page, staff_page = (html.unescape(_get(api, f"/submissions/{sid}", who).text) for who in ("alice", "prof"))
    assert stops <= {s for s in stops if s in staff_page} and not [s for s in stops if s in page]
    for twin in twins:  # no friction chart of it, nor its caption
        assert f'id="figure-friction-x-{twin}"' in staff_page and f'id="figure-friction-x-{twin}"' not in page, twin

    # Released: the student reads every one of them.
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    for twin in twins:
        shown = _get(api, f"/v1/submissions/{sid}/case-runs/{twin}/files/arrays.npz")
        assert shown.status_code == 200 and shown.content == files[twin], twin
    assert _get(api, f"/v1/submissions/{sid}/series").json()["withheld"] == {}
    assert all(s in html.unescape(_get(api, f"/submissions/{sid}").text) for s in stops)



FRICTION_RUNS = {"friction-baseline", "friction-table-0.30", "friction-baseline-colors-swapped"}


def _withheld_everywhere(api, sid, runs: set[str], because: str) -> None:
    """Each of `runs` is withheld from alice on every surface (downloads of the API and the page, the API's case runs,
    the charts' series of both) with `because` in its reason, and shown to the course's instructor."""
    for run in runs:
        refused = _get(api, f"/v1/submissions/{sid}/case-runs/{run}/files/metrics.json")
        assert refused.status_code == 409 and because in refused.json()["detail"], (run, refused.text)
        assert _get(api, f"/submissions/{sid}/case-runs/{run}/arrays.npz").status_code == 409, run
        assert _get(api, f"/v1/submissions/{sid}/case-runs/{run}/files/metrics.json", "prof").status_code == 200
    listed = {r["name"]: r for r in _get(api, f"/v1/submissions/{sid}/case-runs").json()}
    assert all(listed[r]["metrics"] is None for r in runs) and listed["N1"]["metrics"] is not None
    for path in (f"/submissions/{sid}/series.json", f"/v1/submissions/{sid}/series"):
        assert set(_get(api, path).json()["withheld"]) == runs, path


def test_a_checkpoint_submission_withholds_the_lesson_runs_an_item_withheld_in_another_assignment_reads(api, lesson_measured):
    """Issue 44, finding 5-A: withholding is per student and lesson. With B3 withheld until the exercises are
    released, alice's checkpoint submission (graded at once on the lesson's runs, C1-C8 shown) showed friction-baseline
    and friction-table-0.30, whose stops answer B3. They are withheld there too, with the colour-swapped twin; C5
    waits with B3 (its verdict reads the friction runs, hostile pass 6); the release shows them."""
    exercises = create(api, title="Exercises", part="exercises", item_visibility={"B3": "on_release"}).json()["id"]
    checkpoints = create(api).json()["id"]  # immediate: nothing of it withheld
    submitted = submit(api, checkpoints)
    assert submitted.status_code in (200, 201, 202), submitted.text
    sid = submitted.json()["id"]
    grade = grade_of(api, sid, "alice").json()
    items = {i["id"]: i for i in grade["items"]}
    # the checkpoints reading a friction run wait with B3: their verdicts would tell it; the others are shown
    pending = {i for i, item in items.items() if item["verdict"] == "pending"}
    assert set(items) == {f"C{n}" for n in range(1, 9)} and {"C5", "C6"} <= pending, pending
    assert all("decide B3" in items[i]["feedback"] for i in pending), items
    _withheld_everywhere(api, sid, FRICTION_RUNS, "B3, shown once “Exercises” is released")
    staff_c5 = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}["C5"]
    assert (items["C5"]["score"], items["C5"]["evidence"]) == (None, None)
    assert items["C1"] == {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}["C1"]  # reads N4 only

    assert set(grade["withheld_measurements"]) == FRICTION_RUNS
    page = html.unescape(_get(api, f"/submissions/{sid}").text)
    assert 'id="withheld-measurements"' in page and "friction-table-0.30" in page.split('id="withheld-measurements"')[1]

    assert api.client.post(f"/v1/assignments/{exercises}/release", headers=api.as_("prof")).status_code == 200
    for run in FRICTION_RUNS:
        assert _get(api, f"/v1/submissions/{sid}/case-runs/{run}/files/metrics.json").status_code == 200, run
    for path in (f"/submissions/{sid}/series.json", f"/v1/submissions/{sid}/series"):  # no answer kept from before
        assert _get(api, path).json()["withheld"] == {}, path
    assert grade_of(api, sid, "alice").json()["withheld_measurements"] == {}
    assert 'id="withheld-measurements"' not in _get(api, f"/submissions/{sid}").text
    assert {i["id"]: i for i in grade_of(api, sid, "alice").json()["items"]}["C5"] == staff_c5


def test_a_withheld_item_no_measurement_decided_still_withholds_the_runs_it_asks_about(api, measured):
    """Issue 44, finding 5-B: B3 withheld, and the sheet's table exercise changed two factors (not run, B3 graded
    one_factor_violation, naming no run): the lesson's friction runs it asks about were shown. They are withheld by
    what B3's rule reads, whatever its verdict."""
    sheet = reference_sheet()
    sheet["configs"]["table_exercise"] |= {"cube_rho": 800.0}
    create(api, part="exercises", item_visibility={"B3": "on_release"})
    sid = free_graded(api, measured, complete=True, sheet=sheet)
    staff = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}
    assert staff["B3"]["verdict"] == "one_factor_violation" and not staff["B3"]["backends"], staff["B3"]
    _withheld_everywhere(api, sid, FRICTION_RUNS, "B3, shown once")


def test_a_config_of_a_withheld_runs_physics_sampled_otherwise_is_withheld_with_it(api, measured):
    """Issue 44 (hostile pass 2, F1): with A2 withheld (N1-N4), alice's extension at dt 0.02 with 4 substeps (the one
    factor it may change) integrates at N2's internal step of 0.005 s: run on Genesis, its arrays were N2's at every
    other sample, bit for bit, and its metrics.json answered 200 with N2's withheld penetration proxy. It is withheld
    as what it measured: N2's physics (the lesson's physics_key), whatever its sampling and name."""
    sheet = reference_sheet()
    sheet["configs"]["extension"] |= {"dt": 0.02, "substeps": 4}
    create(api, part="exercises", item_visibility={"A2": "on_release"})
    sid = free_graded(api, measured, complete=True, sheet=sheet)
    refused = _get(api, f"/v1/submissions/{sid}/case-runs/sheet.extension/files/metrics.json")
    assert refused.status_code == 409, refused.text
    detail = refused.json()["detail"]
    assert "is a contact run, as N" in detail and "which decides A2" in detail, detail
    assert "sheet.extension" in grade_of(api, sid, "alice").json()["withheld_measurements"]
    assert _get(api, f"/v1/submissions/{sid}/case-runs/sheet.extension/files/metrics.json", "prof").status_code == 200


def test_runs_measured_alike_by_key_by_evidence_by_metrics_or_by_arrays_are_twins(api, measured):
    """Which of a submission's runs measured the same (grader.services.submissions.visibility.measurement_twins), on
    its stored runs: one content key, one evidence row (a reused run), metrics equal but for the case's name, or arrays
    equal bit for bit in an archive of other bytes; equal-sized arrays that differ are no twins."""
    import io

    import numpy as np

    from grader.core.db import new_session
    from grader.core.models import CaseEvidence, Submission, utcnow
    from grader.services.submissions.visibility import measurement_twins
    from tests.grader.core.test_grade_then_complete import _submission_ready_to_grade

    sid = _submission_ready_to_grade(api, measured)
    with new_session() as session:
        runs = {r.name: r for r in session.get(Submission, sid).case_runs}
        runs["N2"].content_key = runs["N3"].content_key = "same inputs"
        runs["N4"].reused_from_id = runs["N1"].id  # N4 finished on N1's measurement
        swapped = runs["friction-baseline-colors-swapped"]
        swapped.metrics = swapped.metrics | {"note": "not the baseline's metrics"}
        evidence = session.get(CaseEvidence, swapped.id)
        arrays = np.load(io.BytesIO(evidence.arrays))
        buffer = io.BytesIO()
        np.savez(buffer, **{k: arrays[k] for k in reversed(arrays.files)})  # the same arrays, written otherwise
        assert buffer.getvalue() != evidence.arrays and len(buffer.getvalue()) == evidence.sizes["arrays.npz"]
        evidence.arrays, evidence.stored_at = buffer.getvalue(), utcnow()
        table = session.get(CaseEvidence, runs["sheet.table_exercise"].id)  # other arrays (times 1 ns on), the same metrics
        arrays = dict(np.load(io.BytesIO(table.arrays)))
        arrays["t"] = arrays["t"] + 1e-9
        buffer = io.BytesIO()
        np.savez(buffer, **arrays)
        table.arrays, table.stored_at = buffer.getvalue(), utcnow()
        session.commit()
        assert measurement_twins(session.get(Submission, sid).case_runs) == {
            "N1": ["N4"], "N4": ["N1"], "N2": ["N3"], "N3": ["N2"],
            "friction-baseline": ["friction-baseline-colors-swapped"],
            "friction-baseline-colors-swapped": ["friction-baseline"],
            "friction-table-0.30": ["sheet.table_exercise"], "sheet.table_exercise": ["friction-table-0.30"]}


def test_a_students_own_config_of_a_withheld_runs_kind_is_withheld_whatever_it_measured(api, measured):
    """Issue 44 (hostile passes 3 and 4): configs of one's own can be built to measure what a withheld lesson run
    measured in more ways than any rule over inputs or outputs can list (a nudged input, a shifted scene, another lane
    order), and another lesson case of the kind tells the rule it shares (friction-table-0.30's pair values told C5's
    pair rule). While a run of a kind is withheld, every run of that kind is withheld with it, saying why; runs of
    another kind stay shown, and the listing keeps nothing that would match a withheld run to another."""
    sheet = reference_sheet()
    sheet["configs"]["extension"] |= {"dt": 0.004, "substeps": 1}  # an internal step no lesson case has
    create(api, part="exercises", item_visibility={"A2": "on_release"})
    sid = free_graded(api, measured, complete=True, sheet=sheet)
    refused = _get(api, f"/v1/submissions/{sid}/case-runs/sheet.extension/files/metrics.json")
    assert refused.status_code == 409, refused.text
    assert "is a contact run, as N1 is, which decides A2" in refused.json()["detail"], refused.text
    withheld = grade_of(api, sid, "alice").json()["withheld_measurements"]
    assert set(withheld) == {"N1", "N2", "N3", "N4", "sheet.extension"}, withheld
    assert _get(api, f"/v1/submissions/{sid}/case-runs/sheet.table_exercise/files/metrics.json").status_code == 200
    listed = {r["name"]: r for r in _get(api, f"/v1/submissions/{sid}/case-runs").json()}
    assert all(listed[r][f] is None for r in withheld
               for f in ("metrics", "provenance", "content_key", "measurement_id", "reused_from_id", "wall_s", "error",
                         "started_at", "finished_at"))
    assert listed["friction-baseline"]["wall_s"] is not None
    # nor in the events (hostile pass 5): a withheld run's states stay, its details (time, error, reuse) do not
    ids = {r["id"]: r["name"] for r in listed.values()}
    events = _get(api, f"/v1/submissions/{sid}/events").json()
    assert all(e["detail"] in (None, "withheld") for e in events if ids.get(e["case_run_id"]) in withheld)
    # nor their times, nor a running state a reused run would lack (pass 6), nor the tries (0: reused)
    mine = [e for e in events if ids.get(e["case_run_id"]) in withheld]
    assert mine and all(e["at"] is None and e["state"] != "running" for e in mine), mine
    assert events[-len(mine):] == mine, events  # last, together: no timed event brackets them
    # an audit re-run of a withheld run says what its source would (pass 14): its events too
    audit = api.client.post(f"/v1/case-runs/{listed['N1']['id']}/audit-reruns", headers=api.as_("prof"),
                            json={"backend": "cpu", "precision": "64", "mode": "isolated"})
    assert audit.status_code == 202, audit.text
    events = _get(api, f"/v1/submissions/{sid}/events").json()
    audited = [e for e in events if e["case_run_id"] == audit.json()["id"]]
    assert audited and all(e["at"] is None and e["detail"] in (None, "withheld") for e in audited), audited
    staff_audited = [e for e in _get(api, f"/v1/submissions/{sid}/events", "prof").json()
                     if e["case_run_id"] == audit.json()["id"]]
    assert any("audit re-run" in (e["detail"] or "") for e in staff_audited), staff_audited
    assert all(listed[r]["tries"] is None for r in withheld) and listed["friction-baseline"]["tries"] is not None
    staff_events = _get(api, f"/v1/submissions/{sid}/events", "prof").json()
    assert any(e["detail"] not in (None, "withheld") for e in staff_events if ids.get(e["case_run_id"]) in withheld)
    # nor on the progress page's JSON and its rendered rows: the state stays, the time, error and reuse do not
    progress = _get(api, f"/submissions/{sid}/progress.json").json()
    rows = {r["name"]: r for r in progress["runs"]}
    assert all(rows[r]["withheld"] and rows[r]["wall_s"] is None and rows[r]["error"] is None
               and rows[r]["reused"] is False and rows[r]["status"] == "done" for r in withheld), rows
    assert rows["friction-baseline"]["wall_s"] is not None and not rows["friction-baseline"]["withheld"]
    # nor its size (N4's 150 internal updates are C1's answer: hostile pass 13): estimated by its kind alone
    assert all(rows[r]["estimate"] is None or (rows[r]["estimate"]["basis"] == "kind"
                                               and rows[r]["estimate"]["updates"] is None) for r in withheld), rows
    assert "internal updates" not in "".join(progress["html"].split('id="run-')[i].split("</tr>")[0]
                                             for i in range(1, progress["html"].count('id="run-') + 1)
                                             if progress["html"].split('id="run-')[i].split('"')[0] in withheld)
    assert progress["html"].count("run-withheld") == len(withheld), progress["html"]
    staff_rows = {r["name"]: r for r in _get(api, f"/submissions/{sid}/progress.json", "prof").json()["runs"]}
    assert all(staff_rows[r]["wall_s"] is not None and not staff_rows[r]["withheld"] for r in withheld)


def test_a_withheld_items_answer_is_not_in_the_reports_own_fields(api, measured):
    """Issue 44 (hostile pass 4): with H6 withheld, results.json still carried the engine version the runs recorded
    (H6's answer) and whether every item was measured. The one-factor findings are H5's answer, and H5, a config item,
    is always shown (pass 7): they stay."""
    create(api, part="exercises", item_visibility={"H6": "on_release"})
    sid = free_graded(api, measured, complete=True)
    staff = _get(api, f"/submissions/{sid}/results.json", "prof").json()
    assert staff["engine_version"] and staff["config_findings"] and "complete" in staff
    mine = _get(api, f"/submissions/{sid}/results.json").json()
    assert not {"engine_version", "complete"} & set(mine), sorted(mine)
    assert mine["config_findings"] == staff["config_findings"]


def test_arrays_equal_but_for_the_time_axis_and_the_recorded_inputs_are_twins(api, measured, monkeypatch):
    """Issue 44 (hostile pass 3): a table exercise at friction 0.5000000001 integrated bit for bit as the baseline
    (single precision holds 0.5), with its own time axis and its own record of the friction it was given: its
    metrics.json answered B2. The arrays' mark reads what was sampled, not `t` nor the 0-d input scalars; one sampled
    value one ulp apart is no twin. (The lesson's physics_key, which also groups these, is turned off here.)"""
    import dataclasses
    import io

    import numpy as np

    from grader.core.db import new_session
    from grader.core.models import CaseEvidence, Submission, utcnow
    from grader.services.submissions import visibility
    from tests.grader.core.test_grade_then_complete import _submission_ready_to_grade

    declared = visibility.lesson
    monkeypatch.setattr(visibility, "lesson",
                        lambda name: dataclasses.replace(declared(name), physics_key=lambda kind, spec: None))
    sid = _submission_ready_to_grade(api, measured)

    def store(session, run, change) -> None:
        evidence = session.get(CaseEvidence, run.id)
        arrays = dict(np.load(io.BytesIO(evidence.arrays)))
        change(arrays)
        buffer = io.BytesIO()
        np.savez(buffer, **arrays)
        evidence.arrays, evidence.stored_at = buffer.getvalue(), utcnow()
        session.commit()

    def nudged(arrays):
        arrays["t"] = arrays["t"] + 1e-12
        for name in [n for n in arrays if arrays[n].ndim == 0]:
            arrays[name] = arrays[name] + 1e-10  # "the friction the engine held", as the nudged config records it

    with new_session() as session:
        runs = {r.name: r for r in session.get(Submission, sid).case_runs}
        swapped = runs["friction-baseline-colors-swapped"]
        swapped.metrics = swapped.metrics | {"note": "not the baseline's metrics"}
        store(session, swapped, nudged)
        assert "friction-baseline-colors-swapped" in visibility.measurement_twins(
            session.get(Submission, sid).case_runs).get("friction-baseline", [])
        sampled = next(n for n, a in np.load(io.BytesIO(session.get(CaseEvidence, swapped.id).arrays)).items()
                       if n != "t" and a.ndim == 1 and a.dtype.kind == "f")
        store(session, swapped, lambda arrays: arrays.__setitem__(sampled, np.concatenate(
            [arrays[sampled][:-1], np.nextafter(arrays[sampled][-1:], np.inf)])))
        assert "friction-baseline-colors-swapped" not in visibility.measurement_twins(
            session.get(Submission, sid).case_runs).get("friction-baseline", [])


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


def test_an_item_whose_verdict_would_tell_a_withheld_one_waits_with_it_on_every_surface(api, measured):
    """Issue 44, hostile pass 6 (high): with B3 withheld, H3 credited on "the high lane is unchanged" at B3's own
    tolerance and H2 on "the low lane goes farther": B3's answer, in one submission; H4's credit on four stop
    distances bounded the withheld runs' values to 2 cm over a few. An item whose rule reads a run of a withheld
    item's kind waits with it, saying with which; the totals count neither; a contact item is shown whole; staff
    see all."""
    aid = create(api, part="exercises", item_visibility={"B3": "on_release"}).json()["id"]
    sid = free_graded(api, measured, complete=True)
    staff = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}
    assert all(staff[i]["verdict"] == "credit" for i in ("H2", "H3", "H4")), staff
    grade = grade_of(api, sid, "alice").json()
    items = {i["id"]: i for i in grade["items"]}
    for i in ("B3", "H1", "H2", "H3", "H4"):
        assert (items[i]["score"], items[i]["verdict"], items[i]["expected"]) == (None, "pending", ""), items[i]
    assert all("decide B3" in items[i]["feedback"] for i in ("H1", "H2", "H3", "H4"))
    assert items["A1"] == staff["A1"]  # reads N4 alone: no friction run
    shown = [i for i, item in items.items() if item["verdict"] != "pending"]
    assert grade["total"] == round(sum(staff[i]["score"] for i in shown), 6)
    assert all(i in grade["pending"] for i in ("B3", "H2", "H3", "H4")), grade["pending"]
    row = _get(api, f"/v1/submissions/{sid}").json()
    assert row["total"] == grade["total"]
    results = _get(api, f"/submissions/{sid}/results.json").json()
    assert {i["id"]: i["verdict"] for i in results["items"]}["H3"] == "pending"
    page = html.unescape(_get(api, f"/submissions/{sid}").text)
    assert staff["H3"]["feedback"] not in page and staff["H4"]["feedback"] not in page

    # Released: every item as staff see it.
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    assert {i["id"]: i for i in grade_of(api, sid, "alice").json()["items"]} == staff


def test_the_gradescope_export_gives_a_reader_of_a_withheld_items_runs_its_visibility(api, measured):
    """Issue 44, hostile pass 6 (high): with B3 on release, the export for Gradescope gave H3 "visible" with B3's
    evidence ("high: 0.2240 -> 0.2241 m") in its output, and a visible header with the total counting B3. Each
    test whose verdict reads a withheld item's runs is gated with it: here a free submission, whose Gradescope
    assignment has no gate of its own, so what is withheld from the student now is hidden (pass 11: another
    assignment's release is no gate of this one); while any test waits, the results' own output leaves the total out
    and the results take the tests' gate."""
    create(api, part="exercises", item_visibility={"B3": "on_release"})
    sid = free_graded(api, measured, complete=True)
    results = _get(api, f"/v1/submissions/{sid}/gradescope.json", "prof")
    assert results.status_code == 200, results.text
    doc = results.json()
    tests = {t["name"].split(":", 1)[0]: t for t in doc["tests"]}
    assert all(tests[i]["visibility"] == "hidden" for i in ("B3", "H1", "H2", "H3", "H4")), tests
    assert doc["visibility"] == "hidden" and " / " not in doc["output"].splitlines()[0], doc["output"]
    b3 = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}["B3"]
    told = [p for p in b3["measured"].split("; ") if p]
    assert told and not [p for t in doc["tests"] if t["visibility"] == "visible" for p in told if p in t["output"]]


def test_a_config_item_is_always_shown_since_the_forms_check_tells_its_answer_before_submitting(api, measured):
    """Issue 44, hostile pass 7 (high and medium): with H5 (does the table exercise change one factor?) withheld, the
    sheet form's Check said "one-factor violation ... cube_rho: 500.0 -> 800.0" before submitting (and again on the
    graded sheet, loaded back into a draft), and whether a sheet.table_exercise run existed said it after (a config
    breaking the rule is never run). A config item is decided from the student's own inputs: it is always shown.
    Withholding it is refused naming the field and the rule; an assignment withholding everything shows it at once."""
    refused = create(api, part="exercises", item_visibility={"H5": "on_release"})
    assert refused.status_code == 422, refused.text
    assert [e for e in refused.json()["errors"] if e["field"] == "item_visibility.H5"
            and "config item is always shown" in e["rule"]], refused.text
    sheet = reference_sheet()
    sheet["configs"]["table_exercise"]["cube_rho"] = 800.0
    assert create(api, part="exercises", visibility="on_release").status_code == 201
    sid = free_graded(api, measured, sheet=sheet)
    staff = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}
    items = {i["id"]: i for i in grade_of(api, sid, "alice").json()["items"]}
    assert items["H5"] == staff["H5"] and staff["H5"]["verdict"] != "pending", staff["H5"]
    held = [i for i in items if i != "H5" and not i.startswith("C")]  # the exercises: every item but the checkpoints
    assert all(items[i]["verdict"] == "pending" for i in held), [(i, items[i]["verdict"]) for i in held]


def test_a_visible_gradescope_test_carries_no_value_of_a_withheld_run(api, measured):
    """Issue 44, hostile pass 9 (high): with A2 on release, A5 (conceptual: its verdict is the answer key's) stayed
    visible in the Gradescope file with "Evidence: N1 proxy ... N2 proxy ...": the N1 -> N2 half of A2's answer. A test
    shown before the runs it reads keeps its verdict, not their numbers."""
    create(api, part="exercises", item_visibility={"A2": "on_release"})
    sid = free_graded(api, measured, complete=True)
    staff = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}
    told = [p for p in staff["A2"]["measured"].split("; ") if p] + [
        p for p in staff["A5"]["measured"].split("; ") if p]
    assert told, staff["A2"]
    doc = _get(api, f"/v1/submissions/{sid}/gradescope.json", "prof").json()
    tests = {t["name"].split(":", 1)[0]: t for t in doc["tests"]}
    visible = [t for t in doc["tests"] if t["visibility"] == "visible"]
    assert tests["A5"]["visibility"] == "visible" and "Evidence withheld" in tests["A5"]["output"], tests["A5"]
    assert tests["A5"]["score"] == staff["A5"]["score"]
    assert not [(t["name"], p) for t in visible for p in told if p in t["output"]]


def test_the_gradescope_file_of_a_checkpoint_submission_withholds_what_an_exercises_assignment_does(
        api, lesson_measured):
    """Issue 44, hostile pass 10 (high): the Gradescope file looked only at the submission's own part. With H1 (the
    pair values) on release in the exercises, a checkpoint submission's file showed C6 visible with every lane's pair
    value before and after, C7's expected answer (B4's) and a total counting C5-C7; the site withheld them. The file
    now reads every item of the lesson an assignment holds, in any part, as the site does."""
    create(api, title="Exercises", part="exercises", item_visibility={"H1": "on_release"})
    checkpoints = create(api).json()["id"]  # immediate
    submitted = submit(api, checkpoints)
    assert submitted.status_code in (200, 201, 202), submitted.text
    sid = submitted.json()["id"]
    mine = {i["id"]: i for i in grade_of(api, sid, "alice").json()["items"]}
    assert {i for i, item in mine.items() if item["verdict"] == "pending"} >= {"C5", "C6", "C7"}, mine
    doc = _get(api, f"/v1/submissions/{sid}/gradescope.json", "prof").json()
    tests = {t["name"].split(":", 1)[0]: t for t in doc["tests"]}
    # another assignment's withholding is no gate of the checkpoints' Gradescope assignment: hidden (pass 11)
    assert all(tests[i]["visibility"] == "hidden" for i in ("C5", "C6", "C7")), tests
    assert tests["C2"]["visibility"] == "visible"  # conceptual, reads no run
    assert "Evidence withheld" in tests["C8"]["output"], tests["C8"]  # conceptual: its friction stops wait
    assert doc["visibility"] == "hidden" and " / " not in doc["output"].splitlines()[0], doc["output"]


def test_the_gradescope_file_gates_each_test_by_its_own_assignment_and_hides_what_two_gates_hold(api, lesson_measured):
    """Issue 44, hostile pass 11 (high): Gradescope's after_due_date and after_published are the Gradescope
    assignment's own due date and publish, independent of each other. With the checkpoints on release and the
    exercises due in a week, the file gave C1-C8 "after_published": on publish, before the exercises were due, C7's
    expected answer (B4's) and C5's pair value were shown. A checkpoint held by its own assignment alone takes that
    assignment's gate; one the exercises withhold too (a reader of their items) is hidden; the results, behind two
    gates, are hidden."""
    create(api, title="Exercises", part="exercises", visibility="after_due")  # due in the future: withheld now
    checkpoints = create(api, visibility="on_release").json()["id"]
    sid = submit(api, checkpoints).json()["id"]
    doc = _get(api, f"/v1/submissions/{sid}/gradescope.json", "prof").json()
    tests = {t["name"].split(":", 1)[0]: t for t in doc["tests"]}
    assert all(tests[i]["visibility"] == "hidden" for i in ("C1", "C5", "C6", "C7")), tests  # readers of B, H, A items
    assert tests["C2"]["visibility"] == "after_published"  # its own gate alone
    assert "Evidence withheld" in tests["C8"]["output"] and tests["C8"]["visibility"] == "after_published"
    assert doc["visibility"] == "hidden"
