"""The report's figures as data (grader/services/reports/series.py, /submissions/ID/series.json): the measured series
read back from the database, to whoever may read the submission, with nothing of a withheld item in them; the report
lists its charts with the series URL and the worker writes no figure file. Real measured runs (the session's Genesis
cases), the real app in-process on SQLite, the worker's own grading functions."""

from __future__ import annotations

import json

import numpy as np

from tests.factories import sheet_results
from tests.grader.services.submissions.test_integrity_withholding import free_graded


def _close(got, want) -> None:
    """Equal to the measured values at DIGITS significant digits of the array's largest magnitude."""
    want = np.asarray(want, dtype=float)
    np.testing.assert_allclose(np.asarray(got, dtype=float), want, rtol=0, atol=float(np.abs(want).max()) * 1e-5)


def _series(api, sid, who):
    return api.client.get(f"/submissions/{sid}/series.json", headers=api.as_(who))


def test_the_series_are_the_stored_arrays_of_every_run_to_its_readers_only(api, measured):
    from grader.core.settings import settings

    sid = free_graded(api, measured, complete=True)
    response = _series(api, sid, "alice")
    assert response.status_code == 200, response.text
    doc = response.json()
    results = sheet_results(measured)
    runs = {r["name"]: r for r in doc["runs"]}
    assert set(runs) <= set(results) and {"N1", "friction-baseline", "sheet.table_exercise"} <= set(runs)
    assert doc["submission"] == sid and all(r["status"] == "ok" for r in runs.values())
    n1 = runs["N1"]
    assert n1["kind"] == "contact" and n1["status"] == "ok" and n1["backend"] == "cpu"
    assert n1["data"] == f"/submissions/{sid}/case-runs/N1/arrays.npz"
    arrays = results["N1"].arrays
    assert {k: len(v) for k, v in n1["series"].items()} == {k: len(arrays["t"]) for k in n1["series"]}
    # The values are the measured ones to DIGITS significant digits, not resampled or recomputed.
    _close(n1["series"]["z"], arrays["z"])
    _close(np.asarray(n1["series"]["clearance_mm"]) / 1e3, arrays["clearance"])
    assert n1["series"]["contact_count"] == arrays["contact_count"].astype(int).tolist()
    assert n1["metrics"]["first_contact_time"] == results["N1"].metrics.first_contact_time
    base = runs["friction-baseline"]
    lanes = {lane["name"]: lane for lane in base["lanes"]}
    low = results["friction-baseline"].arrays
    assert set(lanes) == {lane.name for lane in results["friction-baseline"].spec.lanes}
    _close(lanes["low"]["x"], low["low_x"] - low["low_x"][0])
    _close(lanes["low"]["omega"], np.linalg.norm(low["low_omega"], axis=1))
    stop = results["friction-baseline"].metrics.lane("low").stop
    assert lanes["low"]["stop"]["stopped"] == stop.stopped and lanes["low"]["stop"]["index"] == stop.index
    assert lanes["low"]["color"].startswith("#") and len(lanes["low"]["color"]) == 7
    # Compact: rounded values, no float64 reprs ("0.30000000000000004").
    assert len(response.content) < 200_000 and "0000000" not in response.text

    # A finished submission's series carry a validator: a report view that holds them gets a 304, not a rebuild.
    tag = response.headers["etag"]
    again = api.client.get(f"/submissions/{sid}/series.json", headers=api.as_("alice") | {"If-None-Match": tag})
    assert again.status_code == 304 and again.headers["etag"] == tag

    # The one visibility rule: staff of the course see the same; another student, another course's instructor and
    # a caller without a session do not learn that the submission exists.
    assert _series(api, sid, "prof").json() == doc and _series(api, sid, "tess").status_code == 200
    for stranger in ("bob", "eve"):
        refused = _series(api, sid, stranger)
        assert refused.status_code == 404 and "N1" not in refused.text, (stranger, refused.text)
    assert api.client.get(f"/submissions/{sid}/series.json").status_code == 401
    assert _series(api, sid + 1000, "prof").status_code == 404

    # The report lists its charts with the series as their data, and no figure file was drawn for it.
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    friction = [r for r in runs.values() if r["kind"] == "friction"]
    assert len(friction) >= 3  # contact charts 4 (every contact case overlaid), 3 per friction run
    assert page.count(f'data-src="/submissions/{sid}/series.json"') == 4 + 3 * len(friction)
    assert 'data-chart="friction-x" data-run="friction-baseline"' in page
    assert f"/submissions/{sid}/figures/" not in page and "<img" not in page
    first = results["N1"].metrics.first_contact_time
    assert f"N1 (dt={results['N1'].spec.dt:g} s, substeps={results['N1'].spec.substeps}): first contact t={first:.3f} s" in page
    assert not list((settings.artifacts_dir / "submissions").rglob("*.png")), "the service drew no PNG"


def _same_at_shared_times(a: dict, b: dict) -> bool:
    """Two runs' series equal at every sample time they share (N1 and N4 integrate at one internal step: N4 is N1 at
    every other sample), and they share more than the start."""
    ta, tb = a["series"]["t"], b["series"]["t"]
    # each series of the run: the contact case's own, and each friction lane's (x, vx, omega), in lane order
    def columns(run):
        out = {k: v for k, v in run["series"].items() if k != "t"}
        for n, lane in enumerate(run.get("lanes") or []):
            out |= {f"lane{n}.{k}": lane[k] for k in ("x", "vx", "omega")}
        return out
    ca, cb = columns(a), columns(b)
    if set(ca) != set(cb) or not ca:
        return False
    shared = [(i, tb.index(t)) for i, t in enumerate(ta) if t in tb]
    return len(shared) > 1 and all(ca[k][i] == cb[k][j] for k in ca for i, j in shared)


def test_a_withheld_item_is_not_in_the_series(api, measured):
    from tests.grader.services.setup.test_assignments import create

    create(api, visibility="on_release")  # withholds C1-C8 from the student until released
    sid = free_graded(api, measured, complete=True)
    staff = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("prof")).json()
    withheld = {i["id"]: i for i in staff["items"] if i["id"].startswith("C")}
    mine = _series(api, sid, "alice")
    assert mine.status_code == 200
    # Measurements only, as the PNG figures and the evidence downloads: no item, verdict, expected value,
    # tolerance or lab check, so nothing withheld can be read from them.
    text = mine.text
    for word in ("verdict", "score", "expected", "tolerances", "feedback", "check", "L03 CHECK", "items"):
        assert f'"{word}"' not in text and word not in json.loads(text).keys(), word
    for item in withheld.values():
        assert item["feedback"] not in text and f'"{item["id"]}"' not in text
    # The runs whose measurements decide a withheld item (as the staff's grade records each measured item's runs) are
    # named without their series (issue 31); every other run is what the staff read.
    deciding = {r for i in withheld.values() if i["kind"] == "measured" for r in i["backends"]}
    staff_runs = {r["name"]: r for r in _series(api, sid, "prof").json()["runs"]}
    mine_runs = {r["name"]: r for r in mine.json()["runs"]}
    # With them, every run that measured the same as one of them (issue 44, finding 5: the colour-swapped control is
    # the baseline bit for bit, the lesson's friction-table-0.30 the sheet's table exercise at 0.30; N1 is N4 at every
    # shared sample): the same series wherever their times meet.
    alike = {name for name, run in staff_runs.items() for d in deciding if _same_at_shared_times(run, staff_runs[d])}
    assert alike - deciding, "the reference sheet's runs have twins of the deciding ones"
    # and every run of a withheld run's kind (issue 44, hostile passes 3 and 4)
    own = {name for name, run in staff_runs.items() if any(staff_runs[d]["kind"] == run["kind"] for d in deciding)}
    hidden = deciding | alike | own
    assert deciding and set(mine.json()["withheld"]) == hidden and set(mine_runs) == set(staff_runs)
    for name, run in mine_runs.items():
        assert run == staff_runs[name] if name not in hidden else (run["status"] == "withheld" and "series" not in run)
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert hidden == set(staff_runs)  # the checkpoints read a contact and a friction run: every run is withheld
    assert 'id="figures"' not in page and withheld["C5"]["feedback"] not in page
