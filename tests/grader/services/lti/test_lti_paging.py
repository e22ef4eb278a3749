"""Paging as an LMS pages: a platform written here from the LTI Advantage specs (not lti1p3platform, not the
project's code) splits its roster (NRPS) and its line items (AGS) into pages linked by `Link: <...>; rel="next"`
whose cursor is opaque and case-sensitive, and answers 400 to a cursor it did not send. The tool must follow each
`next` URL exactly as sent, and ask each token for the scopes it uses only."""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, parse_qsl, urlsplit

import pytest
from jwcrypto.jwk import JWK, JWKSet
from jwcrypto.jwt import JWT
from sqlalchemy import select

from tests.grader.services.setup.test_assignments import create
from tests.grader.services.lti.test_lti import LEARNER, _session, graded_attempt, member

CURSOR = "eyJvIjogMiwgIlEiOiAiWnoifQ"  # mixed case, as a base64 cursor is: lower-cased it names nothing
NRPS_SCOPE = "https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly"
SCORE_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/score"
LINEITEM_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/lineitem"
RESULT_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/result.readonly"
CLIENT_ID = "paging-client"



def send_json(handler: BaseHTTPRequestHandler, code: int, data: bytes, link: str | None = None) -> None:
    """A fake platform's JSON answer, with its `Link` header (the next page) where there is one."""
    handler.send_response(code)
    handler.send_header("Content-Type", "application/json")
    handler.send_header("Content-Length", str(len(data)))
    if link:
        handler.send_header("Link", link)
    handler.end_headers()
    handler.wfile.write(data)

class PagingLms:
    """The platform's services: /token (checks the tool's signed client assertion against the tool's JWKS),
    /memberships and /lineitems in two pages each, and each line item's /scores. `roster` and `items` are the second
    page's content after a first page of one entry; `asked` records each token request's scope, `refused` each
    request with a cursor that is not CURSOR."""

    def __init__(self, tool_jwks: dict):
        self.roster: list[dict] = []
        self.items: list[dict] = []
        self.scores: dict[str, dict] = {}
        self.asked: list[str] = []
        self.refused: list[str] = []
        self.created: list[dict] = []
        self.endless = False  # the second page links to itself: `next` forever
        keys = JWKSet.from_json(json.dumps(tool_jwks))
        lms = self

        class Handler(BaseHTTPRequestHandler):
            def _send(self, code: int, body, link: str | None = None):
                send_json(self, code, json.dumps(body).encode(), link)

            def _page(self, first: list, rest: list, path: str):
                """Page 1 without a cursor, page 2 with exactly CURSOR; anything else is a bad request."""
                cursor = parse_qs(urlsplit(self.path).query).get("cursor")
                if cursor is None:
                    return first, f'<{lms.url}{path}?cursor={CURSOR}>; rel="next"'
                if cursor != [CURSOR]:
                    lms.refused.append(self.path)
                    return None, None
                return rest, f'<{lms.url}{path}?cursor={CURSOR}>; rel="next"' if lms.endless else None

            def do_GET(self):
                if self.headers.get("Authorization") != "Bearer token-of-the-lms":
                    return self._send(401, {"error": "no token"})
                path = urlsplit(self.path).path
                if path == "/memberships":
                    members, link = self._page([member("lms-p1", "Page One")], lms.roster, path)
                    if members is None:
                        return self._send(400, {"error": "unknown cursor"})
                    return self._send(200, {"id": f"{lms.url}/memberships", "context": {"id": "ctx"},
                                            "members": members}, link)
                if path == "/lineitems":
                    other = {"id": f"{lms.url}/lineitems/other", "label": "Quiz 1", "scoreMaximum": 5,
                             "tag": "quiz-1"}
                    items, link = self._page([other], lms.items, path)
                    if items is None:
                        return self._send(400, {"error": "unknown cursor"})
                    return self._send(200, items, link)
                return self._send(404, {})

            def do_POST(self):
                raw = self.rfile.read(int(self.headers.get("Content-Length", 0))).decode()
                path = urlsplit(self.path).path
                if path == "/token":
                    form = dict(parse_qsl(raw))
                    JWT(jwt=form["client_assertion"], key=keys)  # raises unless the tool's key signed it
                    lms.asked.append(form["scope"])
                    return self._send(200, {"access_token": "token-of-the-lms", "token_type": "Bearer",
                                            "expires_in": 3600, "scope": form["scope"]})
                if self.headers.get("Authorization") != "Bearer token-of-the-lms":
                    return self._send(401, {"error": "no token"})
                if path == "/lineitems":
                    item = json.loads(raw) | {"id": f"{lms.url}/lineitems/new-{len(lms.created)}"}
                    lms.created.append(item)
                    return self._send(201, item)
                if path.endswith("/scores"):
                    score = json.loads(raw)
                    lms.scores[path.removesuffix("/scores").rsplit("/", 1)[1]] = score
                    return self._send(200, {})
                return self._send(404, {})

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_port}"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def lms(api, monkeypatch):
    """The platform registered for l03, with one LMS course (as a launch would have left it: its services'
    URLs and the AGS scopes offered, result.readonly among them) and the student alice known as LMS user lms-alice."""
    from grader.core.models import Course, LtiContext, LtiIdentity, User
    from grader.services.lti import launch as lti
    from grader.core.settings import settings

    platform = PagingLms(api.client.get("/lti/jwks").json())
    monkeypatch.setattr(settings, "outbound_allow_http", True)
    monkeypatch.setattr(settings, "outbound_allowed_hosts", [f"127.0.0.1:{platform.server.server_port}"])
    with _session() as session:
        course = session.scalar(select(Course).where(Course.name == "l03"))
        registration = lti.create_registration(
            session=session, course=course, issuer="https://paging-lms.example.edu", client_id=CLIENT_ID,
            deployment_ids=["1"], auth_login_url=f"{platform.url}/auth", auth_token_url=f"{platform.url}/token",
            key_set_url=f"{platform.url}/jwks")
        session.add(LtiContext(registration_id=registration.id, context_id="ctx",
                               lineitems_url=f"{platform.url}/lineitems", memberships_url=f"{platform.url}/memberships",
                               scopes=[LINEITEM_SCOPE, RESULT_SCOPE, SCORE_SCOPE]))
        alice = session.scalar(select(User).where(User.name == "alice", User.course_id == course.id))
        session.add(LtiIdentity(registration_id=registration.id, sub="lms-alice", user_id=alice.id))
        session.commit()
    yield platform
    platform.close()


def test_the_roster_follows_a_case_sensitive_next_link(api, lms):
    lms.roster = [member("lms-p2", "Page Two"), member("lms-alice", "Alice Liddell", roles=(LEARNER,))]
    answer = api.client.post("/v1/courses/l03/lti/roster-sync", headers=api.as_("prof"))
    assert answer.status_code == 200, answer.text
    assert lms.refused == []
    synced = answer.json()
    assert (len(synced["added"]), len(synced["updated"])) == (2, 1)  # both pages: p1 and p2 added, alice renamed
    from grader.core.models import LtiIdentity

    with _session() as session:
        subs = {i.sub: i.user.full_name for i in session.scalars(select(LtiIdentity))}
    assert subs == {"lms-alice": "Alice Liddell", "lms-p1": "Page One", "lms-p2": "Page Two"}
    assert lms.asked == [NRPS_SCOPE]  # the roster's token asks for the roster only


def test_the_line_items_follow_a_case_sensitive_next_link_to_the_tools_column(api, lms):
    aid = create(api, title="Lab 3").json()["id"]
    lms.items = [{"id": f"{lms.url}/lineitems/Col-B7", "label": "Lab 3", "scoreMaximum": 10,
                  "tag": f"grader-assignment-{aid}", "resourceId": str(aid)}]
    graded_attempt(aid, "lms-alice", 1, 8.0)
    answer = api.client.post(f"/v1/courses/l03/lti/assignments/{aid}/scores", headers=api.as_("prof"))
    assert answer.status_code == 200, answer.text
    assert [(s["status"], s["error"]) for s in answer.json()] == [("sent", None)]
    assert lms.refused == [] and lms.created == []  # found on page 2: no second column made
    assert lms.scores["Col-B7"]["scoreGiven"] == 8.0
    assert lms.asked == [f"{LINEITEM_SCOPE} {SCORE_SCOPE}"]  # never result.readonly, though offered


# What a sync stopped at a later page says it kept (issue 44, finding 4: pages are stored as they are read): here the
# first page's one learner.
KEPT_THE_FIRST_PAGE = "the 1 learner of the pages before was synced (1 added, 0 updated), nobody was reported as dropped"


def test_a_page_past_the_size_cap_is_reported_with_the_url_and_status_only(api, lms, monkeypatch):
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "outbound_max_bytes", 1_000)
    lms.roster = [member(f"lms-{n}", "N" * 50) for n in range(40)]  # the second page is over the cap
    answer = api.client.post("/v1/courses/l03/lti/roster-sync", headers=api.as_("prof"))
    assert answer.status_code == 409
    assert answer.json()["detail"] == (f"the LMS roster of ctx could not be read: {lms.url}/memberships?cursor="
                                       f"{CURSOR} answered HTTP 200 with more than 1000 bytes; "
                                       f"{KEPT_THE_FIRST_PAGE}")


def test_a_roster_whose_next_links_never_end_is_stopped(api, lms, monkeypatch):
    from grader.services.lti import launch as lti

    monkeypatch.setattr(lti, "MAX_PAGES", 5)
    lms.endless = True
    answer = api.client.post("/v1/courses/l03/lti/roster-sync", headers=api.as_("prof"))
    assert answer.status_code == 409
    assert answer.json()["detail"].endswith(f"{lms.url}/memberships?cursor={CURSOR}: more than 5 pages; stopped; "
                                            f"{KEPT_THE_FIRST_PAGE}")
