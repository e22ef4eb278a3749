"""LTI 1.3 over HTTP on loopback both ways: the tool under uvicorn on PostgreSQL, the platform lti1p3platform's
(tests/grader/test_lti.py's harness), a real cookie jar between them. Launches race here on a real database."""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest

from tests import services
from tests.factories import create_people
from tests.grader.test_lti import CLIENT_ID, DEPLOYMENT_ID, LEARNER, Platform, _Form

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def tool(tmp_path_factory):
    """The platform (its `tool` the tool's URL) registered for course l03; `tokens` and `engine` of the tool's."""
    from sqlalchemy.orm import Session

    from grader.core.db import make_engine, migrate
    from grader.models import Course
    from grader.services import lti

    data_dir = tmp_path_factory.mktemp("lti-tool")
    port = services.free_port()
    platform = Platform(tool=f"http://127.0.0.1:{port}")
    platform.people = {"lms-user-17": {"roles": [LEARNER], "name": "Ada Lovelace", "email": "ada@example.edu"}}
    with services.postgres_database() as database_url:
        migrate(database_url)
        engine = make_engine(database_url)
        with Session(engine) as session:
            platform.tokens = create_people(session, course="l03", other_course="other")
            course = session.query(Course).filter_by(name="l03").one()
            lti.create_registration(session=session, course=course, issuer=platform.issuer, client_id=CLIENT_ID,
                                    deployment_ids=[DEPLOYMENT_ID], auth_login_url=f"{platform.url}/auth",
                                    auth_token_url=f"{platform.url}/token", key_set_url=f"{platform.url}/jwks")
            session.commit()
        env = dict(os.environ, DATABASE_URL=database_url, BROKER_URL=services.REDIS_URL, DATA_DIR=str(data_dir),
                   PYTHONPATH=str(services.ROOT))
        api = services.start_api(env, port, data_dir / "api.log")
        platform.engine = engine
        try:
            yield platform
        finally:
            services.stop(api)
            engine.dispose()
            platform.close()


def _form(browser: httpx.Client, platform: Platform) -> dict:
    started = browser.get(platform.login_url("lms-user-17", "link-1"))
    assert started.status_code == 302, started.text
    form = _Form()
    form.feed(browser.get(started.headers["location"]).text)
    return form.fields


def _post(browser: httpx.Client, platform: Platform, fields: dict) -> httpx.Response:
    return browser.post(f"{platform.tool}/lti/launch", data=fields,
                        headers={"Origin": platform.url, "Sec-Fetch-Site": "cross-site"})


def test_a_student_launches_over_http_and_is_signed_in(tool):
    with httpx.Client() as browser:
        page = _post(browser, tool, _form(browser, tool))
        assert page.status_code == 200, page.text
        target = page.text.split('id="lti-continue" href="')[1].split('"')[0]
        assert target == "/courses/l03"
        assert browser.get(f"{tool.tool}{target}").status_code == 200  # the session cookie came with it


def test_of_two_racing_posts_of_one_launch_one_signs_in(tool):
    with httpx.Client() as browser:
        fields = _form(browser, tool)
        with ThreadPoolExecutor(2) as pool:
            answers = list(pool.map(lambda _: _post(browser, tool, fields), range(2)))
    assert sorted(a.status_code for a in answers) == [200, 400], [a.text[-400:] for a in answers]


def test_the_counted_score_reaches_the_gradebook_over_http(tool):
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from grader.models import Grade, LtiIdentity, Submission, utcnow

    with httpx.Client() as browser:
        assert _post(browser, tool, _form(browser, tool)).status_code == 200
    prof = {"Authorization": f"Bearer {tool.tokens['prof']}"}
    made = httpx.post(f"{tool.tool}/v1/courses/l03/assignments", headers=prof, json={
        "title": "Lab 3", "part": "checkpoints", "open_at": "2020-01-01T00:00:00Z",
        "due_at": "2099-01-01T00:00:00Z", "hard_close_at": "2099-01-02T00:00:00Z"})
    assert made.status_code == 201, made.text
    aid = made.json()["id"]
    with Session(tool.engine) as session:
        user = session.scalar(select(LtiIdentity).where(LtiIdentity.sub == "lms-user-17")).user
        submission = Submission(course_id=user.course_id, student_id=user.id, lesson="L03", sheet={},
                                status="graded", assignment_id=aid, attempt=1, late_seconds=0)
        session.add(submission)
        session.flush()
        session.add(Grade(submission_id=submission.id, rubric_lesson="L03", rubric_version="2", rubric_hash="x",
                          total=4.5, max_total=10.0, report={}, completed_at=utcnow()))
        session.commit()
    # The platform takes the tool's keys from its /lti/jwks over HTTP to grant the token.
    sent = httpx.post(f"{tool.tool}/v1/courses/l03/lti/assignments/{aid}/scores", headers=prof, timeout=30)
    assert sent.status_code == 200 and [s["status"] for s in sent.json()] == ["sent"], sent.text
    (item,) = tool.line_items
    assert item["scores"]["lms-user-17"]["scoreGiven"] == 4.5
