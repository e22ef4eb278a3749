"""LTI 1.3 against a platform that is not ours: `lti1p3platform` (PyPI) signs the launches with its own key, serves
its JWKS, authorization endpoint, token endpoint and gradebook (AGS line items and scores) over HTTP on loopback, and
checks the tool's deep-linking answers; the tool is the real app in-process. A test drives the browser's part: the
platform's login link, the tool's redirect, the platform's auto-posting form."""

from __future__ import annotations

import base64
import json
import threading
import time
from html.parser import HTMLParser
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qsl, urlsplit

import httpx
import pytest
from jwcrypto.jwk import JWK
from lti1p3platform.ltiplatform import LTI1P3PlatformConfAbstract
from lti1p3platform.message_launch import LTIAdvantageMessageLaunchAbstract
from lti1p3platform.oidc_login import OIDCLoginAbstract
from lti1p3platform.registration import Registration
from sqlalchemy import func, select

from tests.grader.services.setup.test_assignments import create

CLIENT_ID, DEPLOYMENT_ID = "grader-tool-client", "deployment-1"
INSTRUCTOR = "http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"
LEARNER = "http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"
TOOL = "http://testserver"


def _pem_pair() -> tuple[str, str]:
    key = JWK.generate(kty="RSA", size=2048)
    return (key.export_to_pem(private_key=True, password=None).decode(), key.export_to_pem().decode())


class _Conf(LTI1P3PlatformConfAbstract):
    def init_platform_config(self, registration: Registration) -> None:
        self._registration = registration

    def get_registration_by_params(self, **kwargs) -> Registration:
        return self._registration


class _Login(OIDCLoginAbstract):
    def set_lti_message_hint(self, **kwargs) -> None:
        self._lti_message_hint = kwargs["link"]

    def get_redirect(self, url: str) -> str:
        return url


class _Launch(LTIAdvantageMessageLaunchAbstract):
    """The platform's answer to the tool's authorization request: the claims of this user and link."""

    def __init__(self, query: dict, conf, platform: Platform):
        super().__init__(None, conf)
        self.query, self.platform = query, platform

    def get_preflight_response(self) -> dict:
        return self.query

    def prepare_launch(self, preflight_response: dict) -> None:
        person = self.platform.people[preflight_response["login_hint"]]
        self.set_user_data(preflight_response["login_hint"], person["roles"], person["name"], person["email"])
        link = preflight_response["lti_message_hint"]
        self.set_resource_link_claim(link, title="Lab 3")
        self.set_launch_context_claim("course-ctx-1", context_title="Genesis L03")
        self.set_custom_parameters_claim(self.platform.links.get(link, {}))
        self.set_id_token_expiration(self.platform.expiration)
        if self.platform.grades:
            self.set_ags(f"{self.platform.url}/lineitems", allow_creating_lineitems=True)
            self.set_nrps(f"{self.platform.url}/memberships")
        if self.platform.deep_linking:
            self.set_dl(f"{self.platform.url}/deep-link-return", title="Add a lab", accept_types={"ltiResourceLink"})

    def get_launch_message(self, include_extra_claims: bool = True) -> dict:
        return super().get_launch_message(include_extra_claims) | self.platform.override

    def get_launch_data(self):
        message, state = super().get_launch_data()
        for claim in self.platform.drop:
            message.pop(claim, None)
        return message, state

    def render_launch_form(self, launch_data: dict, **kwargs) -> str:
        return (f'<form method="post" action="{launch_data["launch_url"]}">'
                f'<input name="id_token" value="{launch_data["id_token"]}">'
                f'<input name="state" value="{launch_data["state"]}"></form>')


class Platform:
    """An LMS as lti1p3platform implements one, on a loopback port: /jwks (its public key) and /auth (the OIDC
    authorization endpoint, answering with the launch form). `override`, `drop` and `expiration` bend the next
    launches the way a faulty or hostile platform would."""

    def __init__(self, tool: str = TOOL):
        self.tool = tool
        self.private_pem, self.public_pem = _pem_pair()
        self.people: dict[str, dict] = {}
        self.links: dict[str, dict] = {}
        self.override: dict = {}
        self.drop: tuple[str, ...] = ()
        self.expiration = 300
        self.jwks: dict | None = None  # served instead of its real JWKS
        self.deep_linking = False  # the next launches are deep-linking requests
        self.grades = True  # launches offer the grades service (AGS) on /lineitems
        self.tool_jwks: dict | None = None  # the tool's keys, for its token requests (the tool is in-process)
        self.line_items: list[dict] = []  # the gradebook: each line item with the scores it received, by user
        self.refuse_scores = False  # the next score posts answer 503
        self.members: list[dict] = []  # the LMS course's roster (NRPS)
        self.token_scopes: list[str] = []  # the scope of each token request the tool made
        self.delays: dict[str, float] = {}  # a slow platform: a request whose path ends with a key waits that long
        self.on_request = lambda path: None  # runs in the server's thread as each request arrives (a test's probe)
        platform = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):
                url = urlsplit(self.path)
                platform.arrived(url.path)
                if url.path == "/jwks":
                    body, kind = json.dumps(platform.jwks or platform.conf().get_jwks()), "application/json"
                elif url.path == "/memberships":
                    if not self._authorized():
                        return self._answer(401, {"error": "bad token"})
                    return self._answer(200, {"id": f"{platform.url}/memberships",
                                              "context": {"id": "course-ctx-1"}, "members": platform.members})
                elif url.path == "/lineitems":
                    if not self._authorized():
                        return self._answer(401, {"error": "bad token"})
                    return self._answer(200, [{k: v for k, v in i.items() if k != "scores"}
                                              for i in platform.line_items])
                else:
                    query = dict(parse_qsl(url.query))
                    body, kind = _Launch(query, platform.conf(), platform).lti_launch(), "text/html"
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.end_headers()
                self.wfile.write(body.encode())

            def _answer(self, code: int, body) -> None:
                self.send_response(code)
                self.send_header("Content-Type", "application/json")
                self.end_headers()
                self.wfile.write(json.dumps(body).encode())

            def _authorized(self) -> bool:
                token = self.headers.get("Authorization", "").removeprefix("Bearer ")
                try:
                    return platform.conf().validate_token(token)
                except Exception:
                    return False

            def do_POST(self):
                raw = self.rfile.read(int(self.headers.get("Content-Length", 0))).decode()
                path = urlsplit(self.path).path
                platform.arrived(path)
                if path == "/token":
                    platform.token_scopes.append(dict(parse_qsl(raw)).get("scope", ""))
                    conf = platform.conf()
                    conf.get_registration().set_tool_key_set(platform.tool_jwks)
                    return self._answer(200, conf.get_access_token(dict(parse_qsl(raw))))
                if not self._authorized():
                    return self._answer(401, {"error": "bad token"})
                if path == "/lineitems":
                    item = json.loads(raw) | {"id": f"{platform.url}/lineitems/{len(platform.line_items)}"}
                    platform.line_items.append(item | {"scores": {}})
                    return self._answer(201, item)
                if platform.refuse_scores:
                    return self._answer(503, {"error": "gradebook down"})
                index = int(path.split("/")[2])
                score = json.loads(raw)
                platform.line_items[index]["scores"][score["userId"]] = score
                return self._answer(200, {})

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_port}"
        self.issuer = self.url
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def conf(self) -> _Conf:
        registration = (Registration().set_iss(self.issuer).set_client_id(CLIENT_ID).set_deployment_id(DEPLOYMENT_ID)
                        .set_launch_url(f"{self.tool}/lti/launch").set_oidc_login_url(f"{self.tool}/lti/login")
                        .set_deeplink_launch_url(f"{self.tool}/lti/launch")
                        .set_tool_key_set_url(f"{self.tool}/lti/jwks")
                        .set_platform_public_key(self.public_pem).set_platform_private_key(self.private_pem))
        return _Conf(registration=registration)

    def arrived(self, path: str) -> None:
        """A request for `path` came: the test's probe sees it, then the answer waits as `delays` says."""
        self.on_request(path)
        time.sleep(next((s for end, s in self.delays.items() if path.endswith(end)), 0.0))

    def login_url(self, user: str, link: str) -> str:
        """The link a person clicks in the LMS: the tool's login initiation URL."""
        login = _Login(None, self.conf())
        login.set_lti_message_hint(link=link)
        return login.initiate_login(user)

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


class _Form(HTMLParser):
    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "form":
            self.action = attrs["action"]
        if tag == "input":
            self.fields = getattr(self, "fields", {}) | {attrs["name"]: attrs["value"]}


def allow(monkeypatch, platform: Platform) -> None:
    """The operator's settings that let the tool fetch from this platform on loopback over plain http: its port
    only, so any other local server stays refused."""
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "outbound_allow_http", True)
    monkeypatch.setattr(settings, "outbound_allowed_hosts", [f"127.0.0.1:{platform.server.server_port}"])


@pytest.fixture
def platform(api, monkeypatch):
    lms = Platform()
    allow(monkeypatch, lms)
    with _session() as session:
        from grader.core.models import Course
        from grader.services.lti import launch as lti

        course = session.scalar(select(Course).where(Course.name == "l03"))
        lti.create_registration(session=session, course=course, issuer=lms.issuer, client_id=CLIENT_ID,
                                deployment_ids=[DEPLOYMENT_ID], auth_login_url=f"{lms.url}/auth",
                                auth_token_url=f"{lms.url}/token", key_set_url=f"{lms.url}/jwks")
        session.commit()
    lms.people = {"lms-user-17": {"roles": [LEARNER], "name": "Ada Lovelace", "email": "ada@example.edu"},
                  "lms-user-1": {"roles": [INSTRUCTOR], "name": "Prof Lin", "email": "lin@example.edu"}}
    yield lms
    lms.close()


def _session():
    from grader.core.db import new_session

    return new_session()


def launch_form(api, platform: Platform, user: str, link: str = "link-1", client=None) -> dict:
    """The browser's way to the launch: the LMS's login link, the tool's redirect to the platform, its form."""
    client = client or api.client
    started = client.get(platform.login_url(user, link), follow_redirects=False)
    assert started.status_code == 302, started.text
    assert started.headers["location"].startswith(f"{platform.url}/auth?")
    form = _Form()
    form.feed(httpx.get(started.headers["location"]).text)
    assert form.action == f"{TOOL}/lti/launch"
    return form.fields


def post_launch(api, fields: dict, client=None, cookie: str | None = None):
    # As a browser sends it from the LMS's page: a cross-site form POST.
    headers = {"Origin": "https://lms.example.edu", "Sec-Fetch-Site": "cross-site"}
    return (client or api.client).post("/lti/launch", data=fields, follow_redirects=False,
                                       headers=headers | ({"Cookie": cookie} if cookie else {}))


def counts() -> dict[str, int]:
    from grader.core.models import LtiIdentity, User, WebSession

    with _session() as session:
        return {table.__tablename__: session.scalar(select(func.count()).select_from(table))
                for table in (User, LtiIdentity, WebSession)}


def landing(page) -> str:
    return page.text.split('id="lti-continue" href="')[1].split('"')[0]


def test_a_student_launches_and_lands_on_the_assignment_signed_in(api, platform):
    aid = create(api, title="Lab 3 checkpoints").json()["id"]
    platform.links["link-1"] = {"assignment_id": str(aid)}
    page = post_launch(api, launch_form(api, platform, "lms-user-17"))
    assert page.status_code == 200, page.text
    assert landing(page) == f"/courses/l03#assignment-{aid}"
    course_page = api.client.get("/courses/l03")
    assert course_page.status_code == 200 and "Lab 3 checkpoints" in course_page.text
    assert "Ada Lovelace" in page.text
    from grader.core.models import LtiIdentity

    with _session() as session:
        (identity,) = session.scalars(select(LtiIdentity)).all()
        assert (identity.sub, identity.user.role, identity.user.course.name) == ("lms-user-17", "student", "l03")
        assert (identity.user.full_name, identity.user.email) == ("Ada Lovelace", "ada@example.edu")


def test_a_second_launch_finds_the_same_user_and_updates_name_and_role(api, platform):
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    before = counts()
    platform.people["lms-user-17"] |= {"name": "Ada King", "roles": [INSTRUCTOR]}
    page = post_launch(api, launch_form(api, platform, "lms-user-17"))
    assert page.status_code == 200 and landing(page) == "/courses/l03/dashboard"
    assert counts() == before | {"web_sessions": before["web_sessions"] + 1}
    from grader.core.models import LtiIdentity

    with _session() as session:
        user = session.scalar(select(LtiIdentity)).user
        assert (user.full_name, user.role) == ("Ada King", "instructor")


def test_an_instructor_lands_on_the_assignments_page(api, platform):
    aid = create(api).json()["id"]
    platform.links["link-1"] = {"assignment_id": str(aid)}
    page = post_launch(api, launch_form(api, platform, "lms-user-1"))
    assert landing(page) == f"/assignments/{aid}"
    assert api.client.get(f"/assignments/{aid}").status_code == 200


def _refused(api, answer, field: str) -> None:
    assert answer.status_code == 400, answer.text
    # the page names the field by its label where it has one (grader.pages.errors.FIELD_LABELS), else as the API does
    shown = {"assignment_id": "<li>assignment: "}.get(field, f"<code>{field}</code>")
    assert "LTI launch refused" in answer.text and shown in answer.text, answer.text
    assert "grader_session" not in answer.headers.get("set-cookie", "")


def test_a_replayed_launch_is_refused(api, platform):
    fields = launch_form(api, platform, "lms-user-17")
    assert post_launch(api, fields).status_code == 200
    before = counts()
    # Even with the login's state cookie kept (the tool deletes it after the launch), the nonce is used up.
    from fastapi.testclient import TestClient

    from grader.main import app

    replay = post_launch(api, fields, client=TestClient(app), cookie=f"lti1p3-{fields['state']}={fields['state']}")
    _refused(api, replay, "id_token.nonce")
    assert counts() == before


def test_a_launch_from_another_browser_than_the_login_is_refused(api, platform):
    # Login CSRF: an attacker's own launch, posted by the victim's browser, lacks the login's state cookie.
    fields = launch_form(api, platform, "lms-user-17")
    before = counts()
    from fastapi.testclient import TestClient

    from grader.main import app

    _refused(api, post_launch(api, fields, client=TestClient(app)), "state")
    assert counts() == before


@pytest.mark.parametrize("bend, field", [
    ({"expiration": -120}, "id_token.exp"),
    ({"expiration": 0}, "id_token.exp"),  # lti1p3platform then signs no exp at all
    ({"override": {"aud": "another-tool"}}, "id_token.aud"),
    ({"override": {"iss": "https://evil.example.edu"}}, "id_token.iss"),
    ({"override": {"https://purl.imsglobal.org/spec/lti/claim/deployment_id": "deployment-9"}},
     "id_token.deployment_id"),
    ({"drop": ("nonce",)}, "id_token.nonce"),
], ids=["expired", "no-expiry", "wrong-audience", "wrong-issuer", "unknown-deployment", "missing-nonce"])
def test_a_bent_launch_is_refused_and_nothing_is_created(api, platform, bend, field):
    for name, value in bend.items():
        setattr(platform, name, value)
    before = counts()
    _refused(api, post_launch(api, launch_form(api, platform, "lms-user-17")), field)
    assert counts() == before


def test_a_student_who_edits_the_token_to_instructor_is_refused(api, platform):
    fields = launch_form(api, platform, "lms-user-17")
    header, payload, signature = fields["id_token"].split(".")
    claims = json.loads(base64.urlsafe_b64decode(payload + "=" * (-len(payload) % 4)))
    claims["https://purl.imsglobal.org/spec/lti/claim/roles"] = [INSTRUCTOR]
    forged = base64.urlsafe_b64encode(json.dumps(claims).encode()).decode().rstrip("=")
    before = counts()
    _refused(api, post_launch(api, fields | {"id_token": f"{header}.{forged}.{signature}"}), "id_token")
    assert counts() == before


def test_a_token_signed_by_another_key_is_refused(api, platform):
    platform.private_pem, _ = _pem_pair()  # signs with a key its JWKS does not publish
    before = counts()
    _refused(api, post_launch(api, launch_form(api, platform, "lms-user-17")), "id_token")
    assert counts() == before


@pytest.mark.parametrize("jwks, field", [({"not_keys": []}, "key_set_url"), ({"keys": ["x"]}, "key_set_url"),
                                         ({"keys": [{"kid": "other", "kty": "RSA"}]}, "id_token")])
def test_a_platform_serving_broken_keys_gets_a_refusal_not_a_crash(api, platform, jwks, field):
    platform.jwks = jwks
    before = counts()
    _refused(api, post_launch(api, launch_form(api, platform, "lms-user-17")), field)
    assert counts() == before


def test_an_instructor_deep_links_an_assignment_that_a_students_launch_then_opens(api, platform):
    aid = create(api, title="Lab 3 exercises").json()["id"]
    platform.deep_linking = True
    fields = launch_form(api, platform, "lms-user-1")
    chooser = post_launch(api, fields)
    assert chooser.status_code == 200 and "Lab 3 exercises" in chooser.text, chooser.text
    # The LMS shows the chooser in its dialog's frame and takes the answer back.
    policy = chooser.headers["content-security-policy"]
    assert f"frame-ancestors 'self' {platform.url}" in policy and f"form-action 'self' {platform.url}" in policy
    answer = api.client.post("/lti/deep-link", data={"state": fields["state"], "assignment_id": aid})
    assert answer.status_code == 200, answer.text
    form = _Form()
    form.feed(answer.text)
    assert form.action == f"{platform.url}/deep-link-return"
    conf = platform.conf()
    conf.get_registration().set_tool_key_set(api.client.get("/lti/jwks").json())
    (item,) = conf.validate_deeplinking_resp({"JWT": form.fields["JWT"]})  # the platform's own check
    assert (item["type"], item["url"], item["custom"]) == ("ltiResourceLink", f"{TOOL}/lti/launch",
                                                           {"assignment_id": str(aid)})
    _refused(api, api.client.post("/lti/deep-link", data={"state": fields["state"], "assignment_id": aid}), "state")
    platform.deep_linking = False
    platform.links["link-new"] = item["custom"]
    student = post_launch(api, launch_form(api, platform, "lms-user-17", "link-new"))
    assert landing(student) == f"/courses/l03#assignment-{aid}"


def test_a_student_cannot_add_a_link(api, platform):
    platform.deep_linking = True
    before = counts()
    _refused(api, post_launch(api, launch_form(api, platform, "lms-user-17")), "id_token.roles")
    assert counts() == before


def test_a_deep_link_answer_from_another_site_is_refused(api, platform):
    aid = create(api).json()["id"]
    platform.deep_linking = True
    fields = launch_form(api, platform, "lms-user-1")
    assert post_launch(api, fields).status_code == 200
    forged = api.client.post("/lti/deep-link", data={"state": fields["state"], "assignment_id": aid},
                             headers={"Sec-Fetch-Site": "cross-site"})
    assert forged.status_code == 403
    other = create(api, who="eve", course="other").json()["id"]
    _refused(api, api.client.post("/lti/deep-link", data={"state": fields["state"], "assignment_id": other}),
             "assignment_id")


def test_a_link_to_another_courses_assignment_is_refused(api, platform):
    other = create(api, who="eve", course="other").json()["id"]
    platform.links["link-1"] = {"assignment_id": str(other)}
    before = counts()
    _refused(api, post_launch(api, launch_form(api, platform, "lms-user-17")), "id_token.custom.assignment_id")
    assert counts() == before


def test_a_login_from_an_unregistered_platform_is_refused(api, platform):
    platform.issuer = "https://unknown-lms.example.edu"
    answer = api.client.get(platform.login_url("lms-user-17", "link-1"), follow_redirects=False)
    _refused(api, answer, "iss")


def test_the_tool_publishes_its_keys_and_keeps_a_rotated_one_a_while(api):
    from grader.services.lti import launch as lti

    first = api.client.get("/lti/jwks").json()["keys"]
    assert len(first) == 1 and {"kid", "n", "e"} <= first[0].keys() and "d" not in first[0]
    with _session() as session:
        lti.rotate_key(session=session)
        session.commit()
    after = [key["kid"] for key in api.client.get("/lti/jwks").json()["keys"]]
    assert len(after) == 2 and after[1] == first[0]["kid"]


def test_an_instructor_registers_a_platform_over_the_api_and_lists_it(api):
    body = {"issuer": "https://canvas.instructure.com", "client_id": "10000000000001", "deployment_ids": ["1:abc"],
            "auth_login_url": "https://sso.canvaslms.com/api/lti/authorize_redirect",
            "auth_token_url": "https://sso.canvaslms.com/login/oauth2/token",
            "key_set_url": "https://sso.canvaslms.com/api/lti/security/jwks"}
    made = api.client.post("/v1/courses/l03/lti/registrations", json=body, headers=api.as_("prof"))
    assert made.status_code == 201, made.text
    listed = api.client.get("/v1/courses/l03/lti/registrations", headers=api.as_("prof")).json()
    assert [r["client_id"] for r in listed] == ["10000000000001"]
    again = api.client.post("/v1/courses/l03/lti/registrations", json=body, headers=api.as_("prof"))
    assert again.status_code == 409
    bad = api.client.post("/v1/courses/l03/lti/registrations", headers=api.as_("prof"),
                          json=body | {"client_id": "2", "key_set_url": "javascript:alert(1)"})
    assert bad.status_code == 422 and bad.json()["errors"][0]["field"] == "key_set_url"
    for who in ("alice", "tess", "eve"):
        assert api.client.post("/v1/courses/l03/lti/registrations", json=body | {"client_id": who},
                               headers=api.as_(who)).status_code in (403, 404)
    assert len(api.client.get("/v1/courses/l03/lti/registrations", headers=api.as_("prof")).json()) == 1


def test_an_operator_registers_a_platform_and_rotates_the_keys_at_the_command_line(api):
    from click.testing import CliRunner

    from grader.cli import main

    args = ["lti", "register", "l03", "--issuer", "https://moodle.example.edu", "--client-id", "abc123",
            "--deployment-id", "1", "--deployment-id", "2",
            "--auth-login-url", "https://moodle.example.edu/mod/lti/auth.php",
            "--auth-token-url", "https://moodle.example.edu/mod/lti/token.php",
            "--key-set-url", "https://moodle.example.edu/mod/lti/certs.php"]
    done = CliRunner().invoke(main, args)
    assert done.exit_code == 0, done.output
    assert "deployments: 1, 2" in done.output
    again = CliRunner().invoke(main, args)
    assert again.exit_code != 0 and "already registered" in again.output
    bad = CliRunner().invoke(main, [*args[:6], "other", *args[7:-1], "ftp://x"])
    assert bad.exit_code != 0 and "key_set_url: must be an absolute http(s) URL" in bad.output
    listed = CliRunner().invoke(main, ["lti", "list", "l03"])
    assert listed.output.count("https://moodle.example.edu") == 1
    first = json.loads(CliRunner().invoke(main, ["lti", "keys"]).stdout)["keys"]
    rotated = json.loads(CliRunner().invoke(main, ["lti", "keys", "--rotate"]).stdout)["keys"]
    assert len(rotated) == 2 and rotated[1]["kid"] == first[0]["kid"] != rotated[0]["kid"]


def graded_attempt(assignment_id: int, sub: str, attempt: int, total: float, max_total: float = 10.0) -> int:
    """A graded attempt of the LMS user `sub`, stored as grading leaves one (scores only; sending reads no report)."""
    from grader.core.models import Grade, LtiIdentity, Submission, utcnow

    with _session() as session:
        user = session.scalar(select(LtiIdentity).where(LtiIdentity.sub == sub)).user
        submission = Submission(course_id=user.course_id, student_id=user.id, lesson="L03", sheet={},
                                status="graded", assignment_id=assignment_id, attempt=attempt, late_seconds=0)
        session.add(submission)
        session.flush()
        session.add(Grade(submission_id=submission.id, rubric_lesson="L03", rubric_version="2", rubric_hash="x",
                          total=total, max_total=max_total, report={}, completed_at=utcnow()))
        session.commit()
        return submission.id


def send(api, aid: int) -> list[dict]:
    answer = api.client.post(f"/v1/courses/l03/lti/assignments/{aid}/scores", headers=api.as_("prof"))
    assert answer.status_code == 200, answer.text
    return answer.json()


def test_counted_scores_reach_the_platforms_gradebook_once_per_change(api, platform):
    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api, title="Lab 3 checkpoints").json()["id"]
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    first = graded_attempt(aid, "lms-user-17", 1, 7.0)
    (sent,) = send(api, aid)
    assert (sent["status"], sent["score"]) == ("sent", 7.0)
    (item,) = platform.line_items
    assert (item["label"], item["scoreMaximum"], item["resourceId"]) == ("Lab 3 checkpoints", 10.0, str(aid))
    score = item["scores"]["lms-user-17"]
    assert (score["scoreGiven"], score["scoreMaximum"], score["gradingProgress"]) == (7.0, 10.0, "FullyGraded")
    assert score["comment"] == f"attempt 1: http://testserver/submissions/{first}"
    assert [s["status"] for s in send(api, aid)] == ["unchanged"]  # idempotent: nothing new is posted
    graded_attempt(aid, "lms-user-17", 2, 9.0)  # the latest attempt counts
    assert [(s["status"], s["score"]) for s in send(api, aid)] == [("sent", 9.0)]
    assert len(platform.line_items) == 1 and platform.line_items[0]["scores"]["lms-user-17"]["scoreGiven"] == 9.0
    # Tokens ask only for what the tool uses of the scopes the platform offered (result.readonly among them): the
    # line item scope while its column must be found or made, then scores alone.
    assert RESULT_SCOPE in launched_scopes(platform)
    assert platform.token_scopes == [f"{LINEITEM_SCOPE} {SCORE_SCOPE}", SCORE_SCOPE]


SCORE_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/score"
LINEITEM_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/lineitem"
RESULT_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/result.readonly"
AGS_CLAIM = "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint"


def launched_scopes(platform: Platform) -> list[str]:
    from grader.core.models import LtiContext

    with _session() as session:
        (context,) = session.scalars(select(LtiContext)).all()
        return context.scopes


def test_a_links_own_line_item_gets_its_scores(api, platform):
    """A launch whose AGS claim names the link's line item (the LMS made one column for the link): that column gets
    the assignment's scores, with a token for scores alone; the tool makes no second column."""
    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api, title="Lab 3 checkpoints").json()["id"]
    platform.links["link-1"] = {"assignment_id": str(aid)}
    platform.line_items.append({"id": f"{platform.url}/lineitems/0", "label": "Lab 3 (the LMS's column)",
                                "scoreMaximum": 10, "scores": {}})
    platform.override = {AGS_CLAIM: {"scope": [LINEITEM_SCOPE, RESULT_SCOPE, SCORE_SCOPE],
                                     "lineitems": f"{platform.url}/lineitems",
                                     "lineitem": f"{platform.url}/lineitems/0"}}
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    graded_attempt(aid, "lms-user-17", 1, 6.5)
    assert [(s["status"], s["score"]) for s in send(api, aid)] == [("sent", 6.5)]
    (item,) = platform.line_items
    assert item["scores"]["lms-user-17"]["scoreGiven"] == 6.5
    assert platform.token_scopes == [SCORE_SCOPE]


def test_a_score_sent_while_a_launch_moves_the_column_goes_again_to_the_new_one(api, platform):
    """A send holds nothing while the platform answers, and stores what it sent only after reading the line item
    again: a launch that names the link's own column while a score is on its way to the old one is not kept waiting,
    and leaves that score unrecorded on the new column, due again, so the next send posts it there."""
    from fastapi.testclient import TestClient

    from grader.core.models import LtiOutbox, LtiScore
    from grader.main import app

    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api, title="Lab 3 checkpoints").json()["id"]
    platform.links["link-1"] = {"assignment_id": str(aid)}
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    graded_attempt(aid, "lms-user-17", 1, 6.0)
    assert [s["status"] for s in send(api, aid)] == ["sent"]  # to the column the tool made: lineitems/0
    graded_attempt(aid, "lms-user-17", 2, 8.0)
    platform.line_items.append({"id": f"{platform.url}/lineitems/1", "label": "the link's own column",
                                "scoreMaximum": 10, "scores": {}})
    relaunched = []

    def relaunch(path: str) -> None:  # while attempt 2's score is posted to lineitems/0, before the answer
        if path == "/lineitems/0/scores" and not relaunched:
            platform.override = {AGS_CLAIM: {"scope": [LINEITEM_SCOPE, SCORE_SCOPE],
                                             "lineitems": f"{platform.url}/lineitems",
                                             "lineitem": f"{platform.url}/lineitems/1"}}
            browser = TestClient(app)
            relaunched.append(post_launch(api, launch_form(api, platform, "lms-user-17", client=browser),
                                          client=browser))

    platform.on_request = relaunch
    assert [(s["status"], s["score"]) for s in send(api, aid)] == [("sent", 8.0)]
    platform.on_request = lambda path: None
    assert relaunched[0].status_code == 200, relaunched[0].text[-500:]
    assert platform.line_items[0]["scores"]["lms-user-17"]["scoreGiven"] == 8.0  # it reached the old column
    with _session() as session:
        assert session.scalars(select(LtiScore)).all() == []  # nothing claims the new column has it
        assert session.scalar(select(LtiOutbox).where(LtiOutbox.assignment_id == aid)).due_at is not None
    assert [(s["status"], s["score"]) for s in send(api, aid)] == [("sent", 8.0)]
    assert platform.line_items[1]["scores"]["lms-user-17"]["scoreGiven"] == 8.0


def test_a_failed_send_is_listed_and_tried_again(api, platform):
    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api).json()["id"]
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    graded_attempt(aid, "lms-user-17", 1, 6.0)
    platform.refuse_scores = True
    (failed,) = send(api, aid)
    assert failed["status"] == "failed" and failed["error"] == f"{platform.url}/lineitems/0/scores answered HTTP 503"
    assert "gradebook down" not in json.dumps(failed)  # the platform's body reaches no answer
    platform.refuse_scores = False
    assert [s["status"] for s in send(api, aid)] == ["sent"]
    assert platform.line_items[0]["scores"]["lms-user-17"]["scoreGiven"] == 6.0


def test_no_score_leaves_while_an_item_is_withheld_then_it_does_on_release(api, platform):
    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api, item_visibility={"C3": "on_release"}).json()["id"]
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    graded_attempt(aid, "lms-user-17", 1, 8.0)
    assert [s["status"] for s in send(api, aid)] == ["withheld"]
    assert all(not item["scores"] for item in platform.line_items)
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    from click.testing import CliRunner

    from grader.cli import main

    done = CliRunner().invoke(main, ["lti", "scores", str(aid)])  # an operator's send
    assert done.exit_code == 0 and "\tsent\t8.0" in done.output, done.output
    assert platform.line_items[0]["scores"]["lms-user-17"]["scoreGiven"] == 8.0


def test_only_the_courses_instructors_send_scores(api, platform):
    aid = create(api).json()["id"]
    for who in ("alice", "tess", "eve"):
        answer = api.client.post(f"/v1/courses/l03/lti/assignments/{aid}/scores", headers=api.as_(who))
        assert answer.status_code in (403, 404), who


def member(sub: str, name: str, roles=(LEARNER,), status: str = "Active") -> dict:
    return {"user_id": sub, "name": name, "email": f"{sub}@example.edu", "roles": list(roles), "status": status}


def test_the_roster_syncs_from_the_lms_adding_updating_and_reporting_dropped_students(api, platform):
    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api).json()["id"]
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    kept = graded_attempt(aid, "lms-user-17", 1, 5.0)
    assert post_launch(api, launch_form(api, platform, "lms-user-1")).status_code == 200
    platform.members = [member("lms-user-17", "Ada King"), member("lms-user-21", "Grace Hopper"),
                        member("lms-user-1", "Prof Lin", roles=(INSTRUCTOR,))]
    sync = lambda: api.client.post("/v1/courses/l03/lti/roster-sync", headers=api.as_("prof"))  # noqa: E731
    first = sync().json()
    assert (len(first["added"]), len(first["updated"]), first["dropped"]) == (1, 1, []), first
    from grader.core.models import LtiIdentity, Submission

    with _session() as session:
        names = {i.sub: (i.user.full_name, i.user.role) for i in session.scalars(select(LtiIdentity))}
    assert names == {"lms-user-17": ("Ada King", "student"), "lms-user-21": ("Grace Hopper", "student"),
                     "lms-user-1": ("Prof Lin", "instructor")}
    before = counts()
    assert sync().json() == {"added": [], "updated": [], "dropped": [], "unchanged": 2}
    platform.members = [member("lms-user-21", "Grace Hopper"), member("lms-user-17", "Ada King", status="Inactive")]
    dropped = sync().json()
    assert dropped["dropped"] == [first["updated"][0]] and dropped["added"] == []
    assert counts() == before  # nobody duplicated, nobody deleted
    with _session() as session:
        assert session.get(Submission, kept) is not None  # a dropped student's submissions stay


def test_a_roster_sync_without_an_lms_roster_is_a_conflict(api, platform):
    platform.grades = False
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    answer = api.client.post("/v1/courses/l03/lti/roster-sync", headers=api.as_("prof"))
    assert answer.status_code == 409 and "roster" in answer.json()["detail"]
    assert api.client.post("/v1/courses/l03/lti/roster-sync", headers=api.as_("alice")).status_code in (403, 404)


def launch_states() -> int:
    from grader.core.models import LtiLaunchState

    with _session() as session:
        return session.scalar(select(func.count()).select_from(LtiLaunchState))


def test_anonymous_logins_are_limited_per_address(api, platform, monkeypatch):
    """Each /lti/login stores a state row: one address gets settings.rate_limit_lti_logins of them, then 429 with
    Retry-After and the rule, nothing stored; another address is not held back by it."""
    from fastapi.testclient import TestClient

    from grader.main import app
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "rate_limit_lti_logins", "3/minute")
    url = platform.login_url("lms-user-17", "link-1")
    assert [api.client.get(url, follow_redirects=False).status_code for _ in range(3)] == [302] * 3
    refused = api.client.get(url, follow_redirects=False)
    assert refused.status_code == 429 and 1 <= int(refused.headers["retry-after"]) <= 60
    assert "at most 3 per 1 minute LTI logins from one address" in refused.text
    assert launch_states() == 3
    other = TestClient(app, client=("203.0.113.9", 50000))
    assert other.get(url, follow_redirects=False).status_code == 302
    assert launch_states() == 4


def test_expired_logins_are_deleted_a_day_after_they_expire(api, platform):
    from datetime import timedelta

    from grader.core.models import LtiLaunchState, LtiRegistration, utcnow

    now = utcnow()
    with _session() as session:
        registration = session.scalar(select(LtiRegistration))
        for name, expired in (("old", now - timedelta(days=1, minutes=1)), ("recent", now - timedelta(hours=23))):
            session.add(LtiLaunchState(registration_id=registration.id, state=name, nonce=name, created_at=expired,
                                       expires_at=expired))
        session.commit()
    assert api.client.get(platform.login_url("lms-user-17", "link-1"), follow_redirects=False).status_code == 302
    with _session() as session:
        states = set(session.scalars(select(LtiLaunchState.state)))
    assert "old" not in states and "recent" in states and len(states) == 2
