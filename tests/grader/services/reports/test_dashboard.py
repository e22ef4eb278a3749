"""The class dashboard on the real app in-process (SQLite): the resend action's access rules and state change, the
predictions against measurements and the per-backend spread in the JSON, and the charts' access rules."""

from __future__ import annotations

import json
from datetime import timedelta

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import CaseRun, Event, Grade, Measurement, Submission, utcnow
from tests.factories import reference_sheet


def _submit(api, who="alice") -> int:
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet() | {"student": who}},
                               headers=api.as_(who))
    assert response.status_code == 202, response.text
    return response.json()["id"]


def _session():
    from grader.core import db

    return Session(db.get_engine())


def _runs(submission_id: int) -> dict[str, CaseRun]:
    with _session() as session:
        return {r.name: r for r in session.scalars(select(CaseRun).where(CaseRun.submission_id == submission_id))}


def _set(case_run_id: int, **values) -> None:
    with _session() as session:
        run = session.get(CaseRun, case_run_id)
        for name, value in values.items():
            setattr(run, name, value)
        session.commit()


def _resend(api, case_run_id: int, who: str = "prof"):
    return api.client.post(f"/v1/case-runs/{case_run_id}/resend", headers=api.as_(who))


def test_only_an_instructor_of_the_course_resends_and_only_a_failed_or_stuck_run(api):
    submission = _submit(api)
    runs = _runs(submission)
    failed, queued = runs["N1"], runs["N2"]
    _set(failed.id, status="failed", result_status="timeout", error="case process timed out after 600 s",
         tries=1, finished_at=utcnow(), artifact_dir="/artifacts/case-runs/1/try-1", provenance={"mode": "warm"},
         metrics={"kind": "contact"})
    for who, code in (("alice", 403), ("bob", 404), ("tess", 403), ("eve", 404)):
        response = _resend(api, failed.id, who)
        assert response.status_code == code, (who, response.text)
    assert _resend(api, 999999, "prof").status_code == 404
    refused = _resend(api, queued.id)
    assert refused.status_code == 409 and "neither failed nor stuck" in refused.json()["detail"]
    sent_before = list(api.sent)

    response = _resend(api, failed.id)
    assert response.status_code == 202, response.text
    body = response.json()
    assert (body["status"], body["delivery"], body["tries"], body["error"]) == ("queued", 2, 0, None)
    assert api.sent == sent_before + [(failed.id, 2, "cpu")]  # its own backend's queue, the new delivery
    with _session() as session:  # back to "never measured": SQL NULL, not a stored JSON null
        assert session.scalar(select(CaseRun.id).where(CaseRun.id == failed.id, CaseRun.metrics.is_(None),
                                                       CaseRun.provenance.is_(None))) == failed.id
    events = api.client.get(f"/v1/submissions/{submission}/events", headers=api.as_("prof")).json()
    resent = [e for e in events if e["state"] == "resent"]
    assert len(resent) == 1 and resent[0]["case_run_id"] == failed.id
    assert "prof" in resent[0]["detail"] and "case process timed out after 600 s" in resent[0]["detail"]
    again = _resend(api, failed.id)  # queued again and within its lease: nothing to re-send
    assert again.status_code == 409 and "neither failed nor stuck" in again.json()["detail"]


def test_a_stuck_run_is_resent_and_a_failed_submission_goes_back_to_running(api):
    submission = _submit(api)
    runs = _runs(submission)
    _set(runs["N3"].id, status="running", worker="lost-host", worker_pid=1, tries=2,
         lease_until=utcnow() - timedelta(minutes=5))
    _set(runs["N4"].id, status="failed", error="gave up after 4 deliveries lost to worker failures", tries=4)
    with _session() as session:
        s = session.get(Submission, submission)
        s.status, s.error = "failed", "grading failed: RuntimeError: boom"
        session.commit()
    problems = {p["case"]: p for p in api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
                ["problems"]}
    assert problems["N3"]["resendable"] and "past its lease" in problems["N3"]["reason"]
    assert problems["N4"]["resendable"] and problems["N4"]["delivery"] == 1
    assert _resend(api, runs["N3"].id).status_code == 202
    assert _resend(api, runs["N4"].id).status_code == 202
    after = _runs(submission)
    assert after["N3"].status == after["N4"].status == "queued"
    assert after["N3"].worker is None and after["N3"].lease_until is None and after["N4"].tries == 0
    state = api.client.get(f"/v1/submissions/{submission}", headers=api.as_("prof")).json()
    assert state["status"] == "running"
    with _session() as session:
        details = [e.detail for e in session.scalars(select(Event).where(Event.submission_id == submission))]
    assert any(d and "grading failed: RuntimeError: boom" in d for d in details)
    assert any(d and "gave up after 4 deliveries" in d and "prof" in d for d in details)


def test_a_failed_run_of_a_graded_submission_is_resent_and_its_grade_kept_superseded(api):
    from grader.core.grades import current_grade, grade_history

    submission = _submit(api)
    run = _runs(submission)["N1"]
    _set(run.id, status="failed", error="case process timed out after 600 s")
    _grade(submission, _report("alice", {"baseline": {"low": 0.5, "high": 0.8}, "modified": {"low": 0.3, "high": 0.8}},
                               {"baseline": {"low": "not_stopped", "high": "not_stopped"},
                                "modified": {"low": "not_stopped", "high": "not_stopped"}}, {}, {}, "not_measured"))
    problem = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()["problems"][0]
    assert problem["resendable"] is True
    assert _resend(api, run.id).status_code == 202
    assert _runs(submission)["N1"].status == "queued"
    with _session() as session:
        assert current_grade(session, submission) is None  # graded again once the run finishes
        history = grade_history(session, submission)
        assert len(history) == 1 and history[0].superseded_at is not None  # the old grade is kept
        details = [e.detail for e in session.scalars(select(Event).where(Event.submission_id == submission))]
    assert any(d and "kept in the history, superseded" in d for d in details)
    state = api.client.get(f"/v1/submissions/{submission}", headers=api.as_("prof")).json()
    assert state["status"] == "running"


def test_the_dashboard_page_resends_with_a_post_form(api):
    submission = _submit(api)
    run = _runs(submission)["N2"]
    _set(run.id, status="failed", error="case process exited 1: boom")
    api.client.post("/sign-in", data={"token": api.tokens["prof"], "next": "/courses/l03/dashboard"})
    page = api.client.get("/courses/l03/dashboard")
    form = f'action="/courses/l03/dashboard/case-runs/{run.id}/resend"'
    assert page.status_code == 200 and form in page.text and 'method="post"' in page.text
    done = api.client.post(f"/courses/l03/dashboard/case-runs/{run.id}/resend", follow_redirects=False)
    assert done.status_code == 303 and done.headers["location"].startswith(f"/courses/l03/dashboard?resent={run.id}")
    assert _runs(submission)["N2"].status == "queued"
    shown = api.client.get(done.headers["location"])
    assert f"Case run {run.id} (N2 of submission {submission}) was re-sent: now queued, delivery 2" in shown.text
    assert form not in shown.text
    refused = api.client.post(f"/courses/l03/dashboard/case-runs/{run.id}/resend", follow_redirects=False)
    assert refused.status_code == 409 and "neither failed nor stuck" in refused.text
    api.client.cookies.clear()
    api.client.post("/sign-in", data={"token": api.tokens["tess"], "next": "/courses/l03/dashboard"})
    _set(run.id, status="failed", error="again")
    assert form not in api.client.get("/courses/l03/dashboard").text  # an auditor sees no button ...
    assert api.client.post(f"/courses/l03/dashboard/case-runs/{run.id}/resend").status_code == 403  # ... nor may


def _report(student: str, h1: dict, h4: dict, evidence_h1: dict, evidence_h4: dict, h4_verdict="credit") -> dict:
    from rubric.scoring import GradeReport, ItemGrade

    def item(item_id, answer, evidence, tolerance, verdict):
        return ItemGrade(id=item_id, question=f"question {item_id}", part="hands_on", kind="measured", points=1,
                         score=1.0 if verdict == "credit" else 0.0, max_score=1, verdict=verdict,
                         prediction=json.dumps(answer), expected="", feedback="", evidence=evidence,
                         backends={"friction-baseline": "cpu", "sheet.table_exercise": "cpu"},
                         tolerances=tolerance)

    items = [item("H1", h1, evidence_h1, {"pair_friction_abs": "0.005 dimensionless"}, "credit"),
             item("H4", h4, evidence_h4, {"reported_stop_distance": "0.02 m"}, h4_verdict)]
    return GradeReport(lesson="L03", student=student, rubric_version="2", rubric_hash="x", engine_version="1.3.3",
                       total=sum(i.score for i in items), max_total=2, complete=True, items=items,
                       config_findings=[]).model_dump(mode="json")


def _grade(submission: int, report: dict) -> None:
    with _session() as session:
        session.add(Grade(submission_id=submission, rubric_lesson="L03", rubric_version="2", rubric_hash="x",
                          total=report["total"], max_total=2, report=report))
        session.get(Submission, submission).status = "graded"
        session.commit()


def test_predictions_are_converted_from_the_sheets_units_and_judged_by_the_grades_tolerance(api):
    alice, bob = _submit(api, "alice"), _submit(api, "bob")
    pairs = {"baseline_low": 0.5, "baseline_high": 0.8, "modified_low": 0.3, "modified_high": 0.8}
    stops = {"baseline_low_stop_distance_m": 0.40, "baseline_high_stop_distance_m": 0.224,
             "modified_low_stop_distance_m": 0.70, "modified_high_stop_distance_m": None}
    _grade(alice, _report("alice", {"baseline": {"low": 0.5, "high": 0.8}, "modified": {"low": 0.3, "high": 0.8}},
                          {"baseline": {"low": {"value": 41.0, "unit": "cm"}, "high": {"value": 224, "unit": "mm"}},
                           "modified": {"low": {"value": 67.5, "unit": "cm"}, "high": "not_stopped"}},
                          pairs, stops, h4_verdict="no_credit"))
    _grade(bob, _report("bob", {"baseline": {"low": 0.1, "high": 0.8}, "modified": {"low": 0.1, "high": 0.8}},
                        {"baseline": {"low": {"value": 0.4, "unit": "m"}, "high": "not_stopped"},
                         "modified": {"low": {"value": 0.7, "unit": "m"}, "high": {"value": 0.2, "unit": "m"}}},
                        pairs, {}, h4_verdict="not_measured"))
    data = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
    plots = {p["item"]: p for p in data["predictions"]}
    assert list(plots) == ["H1", "H4"] and plots["H4"]["unit"] == "m" and plots["H4"]["tolerances"] == [0.02]
    assert plots["H4"]["chart"] == "/courses/l03/dashboard/charts/predictions-H4.svg"
    h4 = {(r["student"], r["run"], r["lane"]): r for r in plots["H4"]["rows"]}
    assert len(h4) == 8
    row = h4[("alice", "baseline", "low")]
    assert row["predicted_as_written"] == "41 cm" and row["predicted"] == pytest.approx(0.41)
    assert row["measured"] == 0.40 and row["difference"] == pytest.approx(0.01) and row["within_tolerance"] is True
    assert h4[("alice", "baseline", "high")]["predicted"] == pytest.approx(0.224)  # 224 mm
    outside = h4[("alice", "modified", "low")]  # 67.5 cm against 0.70 m: 2.5 cm off, the band is 2 cm
    assert outside["difference"] == pytest.approx(-0.025) and outside["within_tolerance"] is False
    both_not_stopped = h4[("alice", "modified", "high")]
    assert both_not_stopped["measured_text"] == "not stopped" and both_not_stopped["within_tolerance"] is True
    assert h4[("bob", "baseline", "low")]["measured_text"] == "not measured"
    assert h4[("bob", "baseline", "low")]["within_tolerance"] is None
    h1 = {(r["student"], r["run"], r["lane"]): r for r in plots["H1"]["rows"]}
    assert h1[("bob", "baseline", "low")]["within_tolerance"] is False
    assert h1[("alice", "modified", "low")]["measured"] == 0.3 and h1[("alice", "modified", "low")]["within_tolerance"]
    assert plots["H1"]["unit"] == "" and plots["H1"]["tolerances"] == [0.005]


def _metrics_contact(name: str, proxy: float) -> dict:
    return {"kind": "contact", "case": name, "penetration_proxy": proxy}


def _metrics_friction(name: str, low: float | None, high: float) -> dict:
    def lane(distance):
        return {"stop": {"stopped": distance is not None, "distance": distance, "detail": ""}}
    return {"kind": "friction", "case": name, "lanes": {"low": lane(low), "high": lane(high)}}


def test_key_measurements_are_grouped_by_backend_and_a_reused_measurement_counts_once(api):
    first, second = _submit(api, "alice"), _submit(api, "bob")
    a, b = _runs(first), _runs(second)
    with _session() as session:
        m = Measurement(content_key="k1", key_inputs={}, case_run_id=a["N1"].id, backend="cpu", provenance={},
                        metrics=_metrics_contact("N1", 0.0132), artifact_dir="/x")
        session.add(m)
        session.flush()
        for run, backend in ((a["N1"], "cpu"), (b["N1"], "cpu")):  # b reused a's measurement
            row = session.get(CaseRun, run.id)
            row.status, row.actual_backend, row.metrics, row.measurement_id = "done", backend, m.metrics, m.id
        row = session.get(CaseRun, b["N2"].id)
        row.status, row.actual_backend, row.metrics = "done", "rocm", _metrics_contact("N2", 0.0078)
        row = session.get(CaseRun, a["N2"].id)
        row.status, row.actual_backend, row.metrics = "done", "cpu", _metrics_contact("N2", 0.0080)
        row = session.get(CaseRun, a["friction-baseline"].id)
        row.status, row.actual_backend, row.metrics = "done", "cpu", _metrics_friction("friction-baseline", None, 0.22)
        session.commit()
    spread = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()["backends"]
    groups = {(g["metric"], g["case"], g["lane"], g["backend"]): g for g in spread["groups"]}
    assert groups[("penetration_proxy", "N1", None, "cpu")]["values"] == [0.0132]  # two runs, one measurement
    assert groups[("penetration_proxy", "N2", None, "rocm")]["values"] == [0.0078]
    assert groups[("penetration_proxy", "N2", None, "cpu")]["median"] == 0.0080
    low = groups[("stop_distance", "friction-baseline", "low", "cpu")]
    assert (low["n"], low["not_stopped"], low["values"], low["median"]) == (1, 1, [], None)
    assert groups[("stop_distance", "friction-baseline", "high", "cpu")]["values"] == [0.22]
    assert [k[:2] for k in groups][:3] == [("penetration_proxy", "N1"), ("penetration_proxy", "N2"),
                                           ("penetration_proxy", "N2")]


def test_the_charts_are_svg_for_the_courses_staff_only(api):
    submission = _submit(api)
    _grade(submission, _report(
        "alice", {"baseline": {"low": 0.5, "high": 0.8}, "modified": {"low": 0.3, "high": 0.8}},
        {"baseline": {"low": {"value": 41.0, "unit": "cm"}, "high": {"value": 22.4, "unit": "cm"}},
         "modified": {"low": {"value": 67.5, "unit": "cm"}, "high": {"value": 22.4, "unit": "cm"}}},
        {"baseline_low": 0.5, "baseline_high": 0.8, "modified_low": 0.3, "modified_high": 0.8},
        {"baseline_low_stop_distance_m": 0.41, "baseline_high_stop_distance_m": 0.224,
         "modified_low_stop_distance_m": 0.675, "modified_high_stop_distance_m": 0.224}))
    urls = [f"/courses/l03/dashboard/charts/{name}.svg" for name in ("predictions-H1", "predictions-H4", "backends")]
    for url in urls:
        for who in ("prof", "tess"):
            response = api.client.get(url, headers=api.as_(who))
            assert response.status_code == 200 and response.headers["content-type"] == "image/svg+xml", (url, who)
            assert response.content.lstrip().startswith(b"<?xml") and b"<svg" in response.content
        for who in ("alice", "bob", "eve"):
            refused = api.client.get(url, headers=api.as_(who))
            assert refused.status_code == 404 and b"<svg" not in refused.content, (url, who)
        api.client.cookies.clear()
        assert api.client.get(url).status_code == 401
    h4 = api.client.get(urls[1], headers=api.as_("prof"))
    assert b"predicted against measured" in h4.content and b"reviewed tolerance" in h4.content
    cached = api.client.get(urls[1], headers=api.as_("prof") | {"If-None-Match": h4.headers["etag"]})
    assert cached.status_code == 304
    unknown = api.client.get("/courses/l03/dashboard/charts/predictions-B2.svg", headers=api.as_("prof"))
    assert unknown.status_code == 404
    page = api.client.get("/courses/l03/dashboard", headers=api.as_("prof")).text
    assert all(f'src="{url}"' in page for url in urls[:2])

    # The charts speak the page's language: a Chinese reader's H4 and backend charts are drawn in Chinese, under an
    # ETag of their own (the English copy a browser holds is never confirmed for the Chinese page)
    zh = {"Accept-Language": "zh-CN,zh;q=0.9"}
    h4_zh = api.client.get(urls[1], headers=api.as_("prof") | zh)
    text = h4_zh.content.decode()
    assert h4_zh.status_code == 200 and h4_zh.headers["etag"] != h4.headers["etag"]
    assert "预测与实测对比" in text and "已审核的容差" in text and "持续停止距离" in text and "基准，低摩擦轨道" in text
    assert "predicted against measured" not in text and "reviewed tolerance" not in text
    assert api.client.get(urls[1], headers=api.as_("prof") | zh | {"If-None-Match": h4.headers["etag"]}
                          ).status_code == 200
    backends_zh = api.client.get(urls[2], headers=api.as_("prof") | zh).content.decode()
    # (this course's grades carry no case run: both panels say so, in Chinese)
    assert "各接触案例的穿透代理量" in backends_zh and "各摩擦轨道的停止距离" in backends_zh, backends_zh[-2000:]
    assert "尚无测量结果" in backends_zh and "no measurement yet" not in backends_zh
    page_zh = api.client.get("/courses/l03/dashboard", headers=api.as_("prof") | zh).text
    assert "H4：持续停止距离 (m)" in page_zh and "<td>基准</td><td>低摩擦轨道</td>" in page_zh


def test_only_the_current_grade_counts_a_superseded_one_stays_out(api):
    submission = _submit(api)
    pairs = {"baseline_low": 0.5, "baseline_high": 0.8, "modified_low": 0.3, "modified_high": 0.8}
    stops = {f"{run}_{lane}_stop_distance_m": 0.3 for run in ("baseline", "modified") for lane in ("low", "high")}
    h1 = {"baseline": {"low": 0.5, "high": 0.8}, "modified": {"low": 0.3, "high": 0.8}}
    old, new = ({run: {lane: {"value": cm, "unit": "cm"} for lane in ("low", "high")} for run in ("baseline", "modified")}
                for cm in (10.0, 30.0))
    _grade(submission, _report("alice", h1, new, pairs, stops))
    with _session() as session:  # the current grade is told by superseded_at, not by which row came last
        session.add(Grade(submission_id=submission, rubric_lesson="L03", rubric_version="1", rubric_hash="y",
                          total=0, max_total=2, report=_report("alice", h1, old, pairs, stops, "no_credit"),
                          superseded_at=utcnow()))
        session.commit()
    data = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
    h4 = next(p for p in data["predictions"] if p["item"] == "H4")
    assert {r["predicted_as_written"] for r in h4["rows"]} == {"30 cm"} and len(h4["rows"]) == 4
    assert data["roster"][0]["total"] == 2 and data["analysis"]["n_reports"] == 1


def test_the_grades_csv_traces_each_row_to_its_attempt_and_latest_keeps_one_per_student(api):
    import csv
    import io

    first, bob, latest = _submit(api, "alice"), _submit(api, "bob"), _submit(api, "alice")
    h1 = {"baseline": {"low": 0.5, "high": 0.8}, "modified": {"low": 0.3, "high": 0.8}}
    h4 = {run: {"low": "not_stopped", "high": "not_stopped"} for run in ("baseline", "modified")}
    for submission, who in ((first, "alice"), (bob, "bob"), (latest, "alice")):
        _grade(submission, _report(who, h1, h4, {}, {}))
    every = api.client.get("/v1/courses/l03/grades.csv", headers=api.as_("prof"))
    rows = list(csv.DictReader(io.StringIO(every.text)))
    assert [(r["student"], int(r["submission_id"])) for r in rows] == [("alice", first), ("bob", bob), ("alice", latest)]
    assert all(r["submitted_at"].endswith("+00:00") for r in rows)
    newest = api.client.get("/v1/courses/l03/grades.csv?latest=true", headers=api.as_("prof"))
    assert "latest-grades.csv" in newest.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(newest.text)))
    assert [(r["student"], int(r["submission_id"])) for r in rows] == [("alice", latest), ("bob", bob)]
    # The dashboard page links both, and each graded roster row its Gradescope results.json.
    api.client.post("/sign-in", data={"token": api.tokens["prof"], "next": "/courses/l03/dashboard"})
    page = api.client.get("/courses/l03/dashboard")
    assert "/courses/l03/grades.csv?latest=true" in page.text and f"/submissions/{latest}/gradescope.json" in page.text
    download = api.client.get(f"/submissions/{latest}/gradescope.json")
    assert download.status_code == 200 and download.json()["score"] == api.client.get(f"/v1/submissions/{latest}/grade", headers=api.as_("prof")).json()["total"]
    assert "attachment" in download.headers["content-disposition"]
    api.client.post("/sign-out")
    api.client.post("/sign-in", data={"token": api.tokens["alice"], "next": "/submissions"})
    assert api.client.get(f"/submissions/{latest}/gradescope.json").status_code == 404  # instructors only
