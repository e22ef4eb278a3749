"""The progress page and the report in the reader's words, in a real browser (Debian's chromium driven by Playwright)
over the API on loopback with PostgreSQL and Redis, measurements from real Genesis runs:

- a submission whose runs wait behind one being run shows each state as stored (running, queued) and a numeric
  estimate, also for a configuration never measured (from warm runs of its kind on its backend);
- the Chinese report shows the student's answers and the expected answers through the form's translations, no English
  answer value left.

No worker runs the queued cases: the runs' states are set as a worker's claim sets them (grader.core.lifecycle.claim),
and the grade task a worker would run is run here (worker.grading.grade_submission). Screenshots, English and Chinese,
desktop and phone width, land in out/screenshots/ (or $SCREENSHOTS_DIR) as progress_*.png and report_answers_*.png."""

from __future__ import annotations

import copy
import os
import re
from contextlib import contextmanager
from dataclasses import dataclass

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from tests import services
from tests.factories import create_people, mark_measured, reference_sheet, sheet_results
from tests.integration.a11y import assert_accessible
from tests.integration.helpers import SHOTS

pytestmark = pytest.mark.integration
COURSE = "l03-words"
PHONE = {"width": 390, "height": 844}
DESKTOP = {"width": 1280, "height": 900}
# Words of the lesson's own that stay as they are in Chinese (case names, symbols, units, rule names, versions).
TECHNICAL = {"N1", "N2", "N3", "N4", "N5", "dt", "substep_dt", "s", "ms", "cm", "m", "max", "min", "mean", "product",
             "genesis", "world"}


@dataclass
class Service:
    url: str
    tokens: dict[str, str]
    engine: object


@contextmanager
def api_over_measurements(folder, measured):
    """The API alone over a fresh PostgreSQL database, its broker a Redis db no worker reads: the lesson's and the
    reference sheet's cases stored as really measured (`measured`, N5 and friction-table-0.30 standing for the sheet's
    configs, as tests.factories.sheet_results says)."""
    from grader.core.db import make_engine, migrate

    with services.postgres_database() as database_url:
        migrate(database_url)
        engine = make_engine(database_url)
        with Session(engine) as session:
            tokens = create_people(session, course=COURSE, other_course="other-course")
            session.commit()
            store_measured(session, sheet_results(measured))
        env = dict(os.environ, DATABASE_URL=database_url, BROKER_URL=services.SPARE_REDIS_URL, DATA_DIR=str(folder),
                   PYTHONPATH=str(services.ROOT))
        port = services.free_port()
        proc = services.start_api(env, port, folder / "api.log")
        try:
            yield Service(f"http://127.0.0.1:{port}", tokens, engine)
        finally:
            services.stop(proc)
            engine.dispose()


def store_measured(session, results: dict, *, by: str = "eve", sheet: dict | None = None) -> None:
    """The cases of `sheet` (default the reference sheet) stored as a worker leaves them after measuring them (done
    case runs of a submission of `by`, reusable Measurements), from real CaseResults by case name."""
    from grader.core import content_key as reuse
    from grader.core.models import Measurement, User
    from grader.services.submissions import submit as submissions
    from rubric import parse_sheet
    from rubric.scoring import cases_to_run

    user = session.scalar(select(User).where(User.name == by))
    specs = cases_to_run(parse_sheet(sheet or reference_sheet()))
    earlier = submissions.create_submission(session=session, student=user, lesson="L03", sheet=reference_sheet(),
                                            specs=[s for s in specs if s.name in results], force_rerun=False)
    session.flush()
    for run in earlier.case_runs:
        mark_measured(run, results[run.name])
        inputs = reuse.key_inputs(run.spec, backend=run.backend, precision=run.precision)
        run.content_key = reuse.content_key(inputs)
        if session.scalar(select(Measurement).where(Measurement.content_key == run.content_key)) is None:
            session.add(Measurement(content_key=run.content_key, key_inputs=inputs, case_run_id=run.id,
                                    backend=run.actual_backend, provenance=run.provenance, metrics=run.metrics,
                                    artifact_dir=run.artifact_dir))
        session.flush()
    session.commit()


@pytest.fixture(scope="module")
def warm_runs(tmp_path_factory) -> list:
    """Contact and friction cases run for real in one warm case process that reuses built scenes, as a worker's slot
    runs them: each structure's first case builds its scene (the warm-up an estimate leaves out), the second reuses
    it."""
    from rubric import BASELINE_CASES
    from worker.case_process import WarmCaseProcess, run_case

    out = tmp_path_factory.mktemp("warm-runs")
    results = []
    with WarmCaseProcess(reuse_scenes=True) as process:
        for i, name in enumerate(["N1", "N1", "friction-baseline", "friction-baseline"]):
            result = run_case(BASELINE_CASES[name], out / f"{i}-{name}", mode="warm", warm_process=process)
            assert result.ok, result.error
            results.append(result)
    assert [r.provenance.scene for r in results] == ["fresh", "reused", "fresh", "reused"]
    return results


@pytest.fixture(scope="module")
def service(tmp_path_factory, measured, warm_runs):
    with api_over_measurements(tmp_path_factory.mktemp("words"), measured) as running:
        with Session(running.engine) as session:  # the warm runs, as earlier submissions' measured runs
            for result in warm_runs:
                store_measured(session, {result.spec.name: result}, by="prof")
        yield running


def signed_in(browser, service, who: str, locale: str):
    context = browser.new_context(viewport=DESKTOP, locale="zh-CN" if locale == "zh" else "en-US")
    page = context.new_page()
    page.goto(f"{service.url}/submissions")
    page.fill("#token", service.tokens[who])
    page.click("form[action='/sign-in'] button[type=submit]")
    page.wait_for_url(f"{service.url}/submissions")
    return context, page


def shoot(page, name: str) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.set_viewport_size(DESKTOP)
    page.screenshot(path=SHOTS / f"{name}.png", full_page=True)
    page.set_viewport_size(PHONE)
    page.screenshot(path=SHOTS / f"{name}_phone.png", full_page=True)
    page.set_viewport_size(DESKTOP)


def own_sheet(who: str, color: list[float], table_friction: float) -> dict:
    """The reference sheet with a cube colour and a table friction no stored run has: configs no one measured yet."""
    sheet = copy.deepcopy(reference_sheet()) | {"student": who}
    sheet["configs"]["extension"]["cube"] = {"color": color}
    sheet["configs"]["table_exercise"]["table"]["friction"] = table_friction
    return sheet


def claim(service, run_id: int) -> None:
    """What a worker's claim leaves on the run: running, started now (grader.core.lifecycle.claim)."""
    from grader.core.lifecycle import claim as worker_claim
    from grader.core.models import CaseRun

    with Session(service.engine) as session:
        run, _ = worker_claim(session=session, case_run_id=run_id, delivery=session.get(CaseRun, run_id).delivery)
        assert run is not None
        session.commit()


def queued(service, submission_id: int) -> list[int]:
    from grader.core.models import CaseRun

    with Session(service.engine) as session:
        return list(session.scalars(select(CaseRun.id).where(CaseRun.submission_id == submission_id,
                                                             CaseRun.status == "queued").order_by(CaseRun.id)))


def test_a_queued_run_behind_a_running_one_shows_both_states_and_a_numeric_estimate(browser, service):
    from grader.client import Client

    bob = Client(service.url, service.tokens["bob"]).submit(own_sheet("bob", [0.1, 0.2, 0.3], 0.35))
    mine = Client(service.url, service.tokens["alice"]).submit(own_sheet("alice", [0.3, 0.2, 0.1], 0.4))
    assert len(queued(service, bob["id"])) == len(queued(service, mine["id"])) == 2  # the configs; the rest reused
    claim(service, queued(service, bob["id"])[0])  # Bob's first config is being run: ahead of all of Alice's
    context, page = signed_in(browser, service, "alice", "en")
    page.goto(f"{service.url}/submissions/{mine['id']}/progress")
    assert page.get_attribute("#progress-summary", "data-phase") == "waiting"
    assert "none is being run yet" in page.inner_text("#progress-summary")
    ahead = page.inner_text("#running-ahead")
    # its time left, or (a reused friction scene runs in well under a second) that it overran its estimate: numbers
    assert re.search(r"running for \d+\.\d s:\s+(about \d+\.\d s left|longer than its estimate of \d+\.\d s)",
                     ahead), ahead
    estimate = page.inner_text("#estimate")
    assert re.search(r"Case time ahead of it, from measured durations: about \d+\.\d s|The time of the run ahead of it is "
                     r"not known\.", estimate) and "Nothing" not in estimate, estimate
    assert re.search(r"Your own cases then take about \d+\.\d s", estimate), estimate
    for name in ("sheet.table_exercise", "sheet.extension"):  # waiting, each with a numeric estimate
        assert re.search(r"^about \d+\.\d s \(never measured", page.inner_text(f"[id='run-{name}'] td.estimate"))
    assert_accessible(page, "the progress page, waiting behind a running run")
    shoot(page, "progress_waiting")

    claim(service, queued(service, mine["id"])[0])  # now one of hers runs, the other waits behind it
    page.reload()
    states = {row.get_attribute("id"): row.locator("[data-state]").get_attribute("data-state")
              for row in page.locator("#runs tbody tr").all()}
    assert {"running", "queued", "done"} <= set(states.values()), states
    assert page.get_attribute("#progress-summary", "data-phase") == "running"
    for name in ("sheet.table_exercise", "sheet.extension"):  # never measured: estimated from their size (issue 49)
        cell = page.inner_text(f"[id='run-{name}'] td.estimate")
        # from its size at its kind's measured time per update: one run says so, not a "median of 1" with a range
        assert re.search(r"^about \d+\.\d s( left)? \(never measured: its [\d,]+ internal updates at the (time per "
                         r"update of one measured (friction|contact) run|median time per update of \d+ measured "
                         r"(friction|contact) runs, \d+\.\d s–\d+\.\d s)\)$", cell), cell
    assert re.search(r"Your own cases then take about \d+\.\d s", page.inner_text("#own-estimate"))
    assert_accessible(page, "the progress page, one run running, one queued")
    shoot(page, "progress_running_queued")
    context.close()

    context, page = signed_in(browser, service, "alice", "zh")
    page.goto(f"{service.url}/submissions/{mine['id']}/progress")
    assert page.get_attribute("html", "lang") == "zh"
    assert "正在运行" in page.inner_text("#progress-summary") and "约" in page.inner_text("#estimate")
    assert_accessible(page, "the Chinese progress page")
    shoot(page, "zh_progress_running_queued")
    context.close()


def answer_cells(page) -> dict[str, tuple[str, str]]:
    rows = page.locator("#items tbody tr")
    return {rows.nth(i).get_attribute("id").removeprefix("item-"):
            (rows.nth(i).locator("td").nth(1).inner_text(), rows.nth(i).locator("td").nth(2).inner_text())
            for i in range(rows.count())}


def test_the_chinese_report_shows_the_answers_and_the_expected_answers_in_chinese(browser, service):
    from grader.client import Client
    from worker.grading import complete_grade, grade_submission

    created = Client(service.url, service.tokens["alice"]).submit(reference_sheet() | {"student": "alice"})
    assert created["status"] == "grading"  # every case reused a stored measurement: only its grade waits
    with Session(service.engine) as session:  # what the grade worker does with it: the grade, then its lab check
        assert grade_submission(session=session, submission_id=created["id"]) is not None
        assert complete_grade(session=session, submission_id=created["id"]) is not None
        session.commit()
    context, page = signed_in(browser, service, "alice", "zh")
    page.goto(f"{service.url}/submissions/{created['id']}")
    page.wait_for_selector("#items")
    cells = answer_cells(page)
    assert len(cells) == 26, sorted(cells)
    english = {item: sorted(set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", " ".join(texts))) - TECHNICAL)
               for item, texts in cells.items()}
    assert not {item: words for item, words in english.items() if words}, english
    assert cells["A2"][0] == "方向：减小" and cells["A3"][0] == "是否一致：是"
    assert cells["C2"] == ("原因：模拟时长不相等", "模拟时长不相等")  # not the raw id unequal_simulated_duration
    # which run on which backend measured an item, in the reader's words (was "N1 on cpu" on the Chinese page)
    backends = page.locator("#item-A3 .backends").inner_text()
    assert backends == "N1（cpu），N4（cpu）", backends
    # a tolerance's name wraps after its underscores, never inside a word ("stop_distance_resol ution")
    assert "stop_<wbr>distance_<wbr>resolution" in page.locator("#item-B2 summary").inner_html()
    assert_accessible(page, "the Chinese report")
    shoot(page, "zh_report_answers")
    context.close()

    context, page = signed_in(browser, service, "alice", "en")
    page.goto(f"{service.url}/submissions/{created['id']}")
    cells = answer_cells(page)
    assert cells["A2"][0] == "direction: decrease" and cells["C2"][1] == "unequal simulated duration"
    assert cells["A3"] == ("agree: yes", "agree: yes")
    shoot(page, "report_answers")
    context.close()


def test_a_refusal_on_the_course_page_names_the_assignment_and_writes_times_as_the_page_does(browser, service):
    from grader.client import Client
    from tests.integration.helpers import at

    prof = Client(service.url, service.tokens["prof"])
    prof.update_course(COURSE, {"timezone": "Asia/Kolkata"})  # a half-hour zone
    shut = prof.create_assignment(COURSE, {"title": "Week 2 friction lab", "part": "sheet", "open_at": at(days=-4),
                                           "due_at": at(days=-3), "hard_close_at": at(days=-2)})
    soon = prof.create_assignment(COURSE, {"title": "Week 5 concepts", "part": "checkpoints", "open_at": at(days=1),
                                           "due_at": at(days=2), "hard_close_at": at(days=3)})
    for locale, closed_words, opens_words in (("en", "“Week 2 friction lab” closed at", "“Week 5 concepts” opens at"),
                                              ("zh", "“Week 2 friction lab”已于", "“Week 5 concepts”于")):
        context, page = signed_in(browser, service, "alice", locale)
        page.goto(f"{service.url}/courses/{COURSE}")
        for assignment, words in ((shut, closed_words), (soon, opens_words)):
            now = page.inner_text(f"#assignment-{assignment['id']}-now")
            assert words in now and "IST" in now, now  # the title, the course's zone named
            assert f"assignment {assignment['id']}" not in now and not re.search(r"\d{4}-\d\d-\d\dT\d", now), now
        assert_accessible(page, f"the course page ({locale})")
        shoot(page, f"{'zh_' if locale == 'zh' else ''}course_refusals")
        context.close()
