"""Rubric versions belong to a course (issue 26): another course's instructor neither overwrites nor sees a course's
version, a published version never changes, a commit names the content hash it previewed, and the regrade form
answers a refusal with its page (never a 500). Over the real app in-process: `prof` teaches l03, `eve` teaches other."""

from __future__ import annotations

import pytest

from tests.factories import rubric_v3

PUBLISH = "/v1/rubrics/versions"


def _worth_50(content: dict) -> dict:
    """Another v3: C2 worth 50 points (the attack's), with its own review record."""
    content["items"] = [item | {"points": 50} if item["id"] == "C2" else item for item in content["items"]]
    content["review"] = content["review"] | {"reviewer": "another course's instructor"}
    return content


def _listed(api, who: str) -> dict[str, dict]:
    response = api.client.get("/v1/rubrics/L03/versions", headers=api.as_(who))
    assert response.status_code == 200, response.text
    return {v["version"]: v for v in response.json()}


def _course_rubric(course: str):
    from sqlalchemy import select

    from grader.core.db import new_session
    from grader.core.rubrics import course_rubric
    from grader.core.models import Course

    with new_session() as session:
        return course_rubric(session, session.scalar(select(Course.id).where(Course.name == course)), "L03")


def test_another_course_publishing_the_same_version_neither_replaces_nor_shows_it(api):
    """The attack: eve (course other) published a different v3 over prof's unused v3 (201), and prof's commit to v3
    then graded l03 under eve's C2 worth 50. Now each course has its own v3 and commits its own content."""
    mine = api.client.post(PUBLISH, json=rubric_v3(), headers=api.as_("prof"))
    assert mine.status_code == 201, mine.text
    theirs = api.client.post(PUBLISH, json=_worth_50(rubric_v3()), headers=api.as_("eve"))
    assert theirs.status_code == 201, theirs.text  # eve's course's own v3
    assert theirs.json()["content_hash"] != mine.json()["content_hash"]

    listed = _listed(api, "prof")
    assert listed["3"]["published_by"] == "prof" and listed["3"]["content_hash"] == mine.json()["content_hash"]
    assert {v["published_by"] for v in listed.values()} == {None, "prof"}
    assert "another course's instructor" not in str(listed)
    assert {v["published_by"] for v in _listed(api, "eve").values()} == {None, "eve"}
    assert _listed(api, "eve")["3"]["content_hash"] == theirs.json()["content_hash"]
    page = api.client.get("/courses/l03/rubrics", headers=api.as_("prof"))
    assert page.status_code == 200 and "by eve" not in page.text and theirs.json()["content_hash"][:12] not in page.text

    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    assert preview["content_hash"] == mine.json()["content_hash"]
    commit = {"version": "3", "content_hash": preview["content_hash"]}
    assert api.client.post("/v1/courses/l03/regrades", json=commit, headers=api.as_("prof")).status_code == 201
    graded_under = _course_rubric("l03")  # what the worker grades l03's new submissions under
    assert graded_under.content_hash == mine.json()["content_hash"]
    assert next(i.points for i in graded_under.items if i.id == "C2") != 50
    assert _course_rubric("other").version == "2"  # eve's v3 is hers to commit, not committed by prof's


def test_a_published_version_never_changes_and_a_shipped_one_is_not_published_over(api):
    first = api.client.post(PUBLISH, json=rubric_v3(), headers=api.as_("prof"))
    assert first.status_code == 201
    again = api.client.post(PUBLISH, json=rubric_v3(), headers=api.as_("prof"))
    assert again.status_code == 201 and again.json()["content_hash"] == first.json()["content_hash"]  # idempotent
    changed = api.client.post(PUBLISH, json=_worth_50(rubric_v3()), headers=api.as_("prof"))
    assert changed.status_code == 409 and "immutable" in changed.json()["detail"], changed.text
    assert _listed(api, "prof")["3"]["content_hash"] == first.json()["content_hash"]

    over_shipped = rubric_v3() | {"version": "2"}
    response = api.client.post(PUBLISH, json=over_shipped, headers=api.as_("eve"))
    assert response.status_code == 409 and "shipped with the service" in response.json()["detail"], response.text
    assert _listed(api, "eve")["2"]["source"] == "shipped"


def test_another_courses_version_is_unknown_everywhere(api):
    theirs = api.client.post(PUBLISH, json=_worth_50(rubric_v3()), headers=api.as_("eve")).json()
    assert "3" not in _listed(api, "prof") and "3" not in _listed(api, "tess")
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof"))
    assert preview.status_code == 404 and "known: 1, 2" in preview.json()["detail"], preview.text
    commit = {"version": "3", "content_hash": theirs["content_hash"]}
    refused = api.client.post("/v1/courses/l03/regrades", json=commit, headers=api.as_("prof"))
    assert refused.status_code == 404 and "known: 1, 2" in refused.text and theirs["content_hash"] not in refused.text
    page = api.client.get("/courses/l03/regrade?version=3", headers=api.as_("prof"))
    assert page.status_code == 404 and "another course" not in page.text and "known: 1, 2" in page.text
    rubrics = api.client.get("/courses/l03/rubrics", headers=api.as_("prof"))
    assert 'id="version-3"' not in rubrics.text
    assert api.client.get("/v1/courses/l03/regrades", headers=api.as_("prof")).json() == []  # nothing committed


def test_a_commit_names_the_content_hash_it_previewed(api):
    mine = api.client.post(PUBLISH, json=rubric_v3(), headers=api.as_("prof")).json()
    theirs = api.client.post(PUBLISH, json=_worth_50(rubric_v3()), headers=api.as_("eve")).json()
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    assert preview["content_hash"] == mine["content_hash"]

    missing = api.client.post("/v1/courses/l03/regrades", json={"version": "3"}, headers=api.as_("prof"))
    assert missing.status_code == 422 and [e["field"] for e in missing.json()["errors"]] == ["content_hash"]
    other = api.client.post("/v1/courses/l03/regrades", json={"version": "3", "content_hash": theirs["content_hash"]},
                            headers=api.as_("prof"))
    assert other.status_code == 409 and other.json()["detail"].startswith("content_hash:"), other.text
    assert [e["field"] for e in other.json()["errors"]] == ["content_hash"]
    assert api.client.get("/v1/courses/l03/regrades", headers=api.as_("prof")).json() == []  # nothing half-stored
    assert _course_rubric("l03").version == "2"

    page = api.client.get("/courses/l03/regrade?version=3", headers=api.as_("prof"))
    assert f'name="content_hash" value="{mine["content_hash"]}"' in page.text


@pytest.mark.parametrize(("form", "code", "shown"), [
    ({"version": "9", "lesson": "L03"}, 404, "no rubric version &#39;9&#39;"),
    ({"version": "2", "lesson": "L99"}, 404, "lesson L99 has no rubric version"),
    ({"version": "2", "lesson": "../L03"}, 422, "lesson"),
    ({"version": "", "lesson": "L03"}, 422, "version"),
    ({"version": "1", "lesson": "L03"}, 409, "archived"),
    ({"version": "2", "lesson": "L03", "content_hash": "0" * 64}, 409, "content_hash"),
])
def test_the_regrade_form_answers_a_refusal_with_the_regrade_page(api, form, code, shown):
    """Once a 500: an unknown version or lesson posted to the commit form."""
    hashes = {"content_hash": "a" * 64} if "content_hash" not in form else {}
    response = api.client.post("/courses/l03/regrade", data=form | hashes, headers=api.as_("prof"),
                               follow_redirects=False)
    assert response.status_code == code, response.text
    assert 'id="regrade-error"' in response.text and shown in response.text
    assert api.client.get("/v1/courses/l03/regrades", headers=api.as_("prof")).json() == []


def test_the_regrade_form_commits_the_previewed_content(api):
    api.client.post(PUBLISH, json=rubric_v3(), headers=api.as_("prof"))
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    without = api.client.post("/courses/l03/regrade", data={"version": "3"}, headers=api.as_("prof"))
    assert without.status_code == 422 and "content_hash" in without.text
    done = api.client.post("/courses/l03/regrade", data={"version": "3", "content_hash": preview["content_hash"]},
                           headers=api.as_("prof"), follow_redirects=False)
    assert done.status_code == 303, done.text
    assert [r["version"] for r in api.client.get("/v1/courses/l03/regrades", headers=api.as_("prof")).json()] == ["3"]


def test_migration_0013_gives_a_published_version_its_publishers_course(tmp_path):
    from alembic import command
    from sqlalchemy import text
    from sqlalchemy.exc import IntegrityError

    from grader.core.db import make_engine, migrate
    from tests.grader.core.test_storage import alembic_config

    url = f"sqlite:///{tmp_path / 'm.db'}"
    migrate(url)
    command.downgrade(alembic_config(url), "0012")
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO courses (name, created_at, timezone) VALUES ('a', CURRENT_TIMESTAMP, 'UTC'), "
                          "('b', CURRENT_TIMESTAMP, 'UTC')"))
        conn.execute(text("INSERT INTO users (course_id, name, role, created_at) VALUES (2, 'p', 'instructor', "
                          "CURRENT_TIMESTAMP)"))
        for version, by in (("2", "NULL"), ("3", "1")):
            conn.execute(text("INSERT INTO rubric_versions (lesson, version, content_hash, content, source, "
                              f"published_by_id, published_at) VALUES ('L03', '{version}', 'h', '{{}}', 's', {by}, "
                              "CURRENT_TIMESTAMP)"))
    command.upgrade(alembic_config(url), "head")
    with engine.begin() as conn:
        owners = dict(conn.execute(text("SELECT version, course_id FROM rubric_versions")).all())
        assert owners == {"2": None, "3": 2}
        conn.execute(text("INSERT INTO rubric_versions (course_id, lesson, version, content_hash, content, source, "
                          "published_at) VALUES (1, 'L03', '3', 'h', '{}', 's', CURRENT_TIMESTAMP)"))  # course a's v3
    with pytest.raises(IntegrityError), engine.begin() as conn:  # a second shipped v2: NULLs are not distinct here
        conn.execute(text("INSERT INTO rubric_versions (lesson, version, content_hash, content, source, "
                          "published_at) VALUES ('L03', '2', 'h', '{}', 's', CURRENT_TIMESTAMP)"))
    engine.dispose()


def test_the_cli_commits_the_content_hash_its_preview_showed(api, monkeypatch):
    from click.testing import CliRunner
    from fastapi.testclient import TestClient

    from grader.cli import main, rubric
    from grader.client import Client
    from grader.main import app

    def client_on(url, token):  # the CLI's client, talking to the in-process app
        client = Client(url, token)
        client.http = TestClient(app, base_url="http://testserver/v1", headers={"Authorization": f"Bearer {token}"})
        return client

    monkeypatch.setattr(rubric, "_client", client_on)
    published = api.client.post(PUBLISH, json=rubric_v3(), headers=api.as_("prof")).json()
    done = CliRunner().invoke(main, ["rubric", "regrade", "l03", "3", "--commit", "--token", api.tokens["prof"]])
    assert done.exit_code == 0 and published["content_hash"][:12] in done.output, done.output
    assert "regrade #1 committed by prof" in done.output
    listed = CliRunner().invoke(main, ["rubric", "list", "--token", api.tokens["eve"]])
    assert listed.exit_code == 0 and "v3" not in listed.output, listed.output  # prof's course's, not eve's
