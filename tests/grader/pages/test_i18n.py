"""Every student page in English and Chinese (grader.i18n, grader.pages.templates): the language chosen per request
(the switch's cookie > Accept-Language > English), every msgid a student page uses translated, the services'
messages, dates and numbers in the reader's locale, the lesson's questions from the translations file beside the
rubric without touching a published version, and a grade that never depends on the page's language."""

from __future__ import annotations

import html
import re
import subprocess
from datetime import datetime
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml
from babel.messages.extract import extract_from_dir, extract_from_file
from babel.messages.frontend import parse_mapping_cfg

from grader import i18n
from tests.factories import REFERENCE_YAML
from tests.grader.services.setup.test_assignments import at, create
from tests.grader.pages.test_sheet_form import form_fields, import_yaml

ROOT = Path(__file__).resolve().parents[3]
TEMPLATES = ROOT / "grader" / "templates"
# Every template a student's pages render (their own, included and imported ones).
STUDENT_TEMPLATES = ["base.html", "reports/course_page.html", "submissions/sheet_form.html",
                     "submissions/submit_confirm.html", "submissions/progress.html", "submissions/_progress_live.html",
                     "submissions/report.html", "submissions/_attempt.html", "submissions/_grade_history.html",
                     "submissions/_item_review.html", "submissions/submissions.html", "identity/sign_in.html",
                     "identity/sign_in_link.html", "error.html", "not_found.html", "lti/launched.html"]
ZH = {"Accept-Language": "zh-CN,zh;q=0.9,en;q=0.8"}


def zh(api, who: str = "alice") -> dict:
    return {**api.as_(who), **ZH}


def template_msgids(name: str) -> list[str]:
    """The msgids `make i18n` extracts from one template (Babel's Jinja2 extractor, as babel.cfg configures it)."""
    found = extract_from_file("jinja2", str(TEMPLATES / name), options={"extensions": "jinja2.ext.i18n"})
    return [m if isinstance(m, str) else m[0] for _, m, _, _ in found]


def walk_missing() -> set[str]:
    return {msgid for locale, msgid in i18n.MISSING if locale == "zh"}


def test_accept_language_picks_chinese_and_the_switch_overrides_it(api):
    page = api.client.get("/sign-in", headers=ZH)
    assert page.status_code == 200
    assert '<html lang="zh">' in page.text and "<h1>登录</h1>" in page.text and "API 令牌" in page.text
    # The browser's q-values are read: English first stays English, an unknown language falls back to English.
    assert '<html lang="en">' in api.client.get("/sign-in", headers={"Accept-Language": "en;q=1, zh;q=0.5"}).text
    assert "<h1>Sign in</h1>" in api.client.get("/sign-in", headers={"Accept-Language": "de-DE, fr"}).text
    # The switch on the page: a form with both languages, each named in its own language.
    assert 'action="/language"' in page.text and 'value="en" lang="en"' in page.text and ">English</button>" in page.text
    assert 'value="zh" lang="zh"' in page.text and ">中文</button>" in page.text
    switched = api.client.post("/language", data={"locale": "en", "next": "/sign-in?next=/submissions"},
                               headers=ZH, follow_redirects=False)
    assert switched.status_code == 303 and switched.headers["location"] == "/sign-in?next=/submissions"
    assert "grader_lang=en" in switched.headers["set-cookie"] and "HttpOnly" in switched.headers["set-cookie"]
    # The cookie (kept by the client) now wins over Accept-Language.
    assert "<h1>Sign in</h1>" in api.client.get("/sign-in", headers=ZH).text
    api.client.post("/language", data={"locale": "zh", "next": "/sign-in"})
    assert "<h1>登录</h1>" in api.client.get("/sign-in", headers={"Accept-Language": "en"}).text


def test_the_switch_is_origin_checked_and_refuses_what_it_does_not_know(api):
    cross = api.client.post("/language", data={"locale": "zh"}, headers={"Sec-Fetch-Site": "cross-site"})
    assert cross.status_code == 403 and "grader_lang" not in cross.headers.get("set-cookie", "")
    unknown = api.client.post("/language", data={"locale": "fr"})
    assert unknown.status_code == 422 and "locale" in unknown.text and "must be one of en, zh" in unknown.text
    # Never a redirect to another site.
    away = api.client.post("/language", data={"locale": "zh", "next": "//evil.example/"}, follow_redirects=False)
    assert away.headers["location"] == "/submissions"


def test_every_msgid_of_the_student_pages_has_a_chinese_translation():
    """Fails as soon as a template a student sees uses a msgid the zh catalogue lacks (absent, empty or fuzzy)."""
    have = i18n.known("zh")
    used = {name: template_msgids(name) for name in STUDENT_TEMPLATES if (TEMPLATES / name).is_file()}
    assert sum(len(ids) for ids in used.values()) > 250
    missing = {name: [m for m in ids if m not in have] for name, ids in used.items()}
    assert {name: ids for name, ids in missing.items() if ids} == {}, "run `make i18n` and translate these"
    coded = [msgid for _, msgid in i18n.PATTERNS] + i18n.MESSAGES + i18n.WORDS
    assert [m for m in coded if m not in have] == []


def extracted_msgids() -> dict[str, list[str]]:
    """Every msgid `make i18n` extracts, by file: babel.cfg's own mapping (the Python of grader/, N_() markers
    included, and its templates), so a page or module added later is checked without naming it here."""
    with (ROOT / "babel.cfg").open(encoding="utf-8") as f:
        method_map, options_map = parse_mapping_cfg(f)

    def in_grader(path: str) -> bool:
        parts = Path(path).relative_to(ROOT).parts
        return parts[0] == "grader" and not any(p.startswith((".", "__")) for p in parts)

    found: dict[str, list[str]] = {}
    for filename, _, msgid, _, _ in extract_from_dir(ROOT, method_map, options_map, directory_filter=in_grader):
        found.setdefault(filename, []).append(msgid if isinstance(msgid, str) else msgid[0])
    return found


def untranslated_in(used: dict[str, list[str]], have: frozenset[str]) -> dict[str, list[str]]:
    missing = {name: sorted({m for m in ids if m not in have}) for name, ids in used.items()}
    return {name: ids for name, ids in missing.items() if ids}


def test_every_msgid_of_every_page_and_module_has_a_chinese_translation():
    """Staff pages too (dashboard, set-up, assignment forms, rubric review and draft, regrade, reviews, LTI admin):
    every msgid extracted from any template or module of grader/ has a zh msgstr (not absent, empty or fuzzy)."""
    used = extracted_msgids()
    staff = {"reports/dashboard.html", "setup/courses.html", "setup/assignments.html", "setup/assignment_form.html",
             "rubrics/rubrics.html", "rubrics/tolerance_review.html", "rubrics/tolerance_review_draft.html",
             "rubrics/regrade.html", "submissions/review_requests.html", "lti/outbox.html", "setup/roster_issued.html"}
    # templates by their path under grader/templates (one folder per context), modules by their file name
    names = {str(Path(name).relative_to("grader/templates")) if name.startswith("grader/templates/") else Path(name).name
             for name in used}
    assert staff | set(STUDENT_TEMPLATES) | {"i18n.py", "sheet_form.py"} <= names, sorted(names)
    assert len({m for ids in used.values() for m in ids}) > 600
    assert untranslated_in(used, i18n.known("zh")) == {}, "run `make i18n` and translate these"


def test_an_emptied_staff_translation_is_caught(tmp_path, monkeypatch):
    """The check above can fail: one staff page's msgstr emptied (as a new msgid arrives) is named, with its page."""
    from babel.messages.pofile import read_po, write_po

    with i18n.po_path("zh").open("rb") as f:
        catalog = read_po(f, locale="zh")
    assert catalog["Set the time zone"].string
    catalog["Set the time zone"].string = ""
    (tmp_path / "zh" / "LC_MESSAGES").mkdir(parents=True)
    with (tmp_path / "zh" / "LC_MESSAGES" / "messages.po").open("wb") as f:
        write_po(f, catalog)
    monkeypatch.setattr(i18n, "TRANSLATIONS_DIR", tmp_path)
    i18n.translations.cache_clear()
    try:
        assert untranslated_in(extracted_msgids(), i18n.known("zh")) == {
            "grader/templates/setup/courses.html": ["Set the time zone"]}
    finally:
        monkeypatch.undo()
        i18n.translations.cache_clear()


def test_every_translation_keeps_the_placeholders_of_its_msgid():
    """Babel's python-format checks: a translation that drops or renames a %(name)s would fail the page."""
    from babel.messages.pofile import read_po

    with i18n.po_path("zh").open("rb") as f:
        catalog = read_po(f, locale="zh")
    problems = [(message.id, [str(e) for e in errors]) for message, errors in catalog.check()]
    assert problems == []
    for message in catalog:  # and the {when}/{status} of the page script's messages
        if message.id and message.string and isinstance(message.id, str):
            assert re.findall(r"{[a-z]+}", message.id) == re.findall(r"{[a-z]+}", message.string), message.id


def test_a_catalogue_missing_a_template_msgid_is_caught(tmp_path, monkeypatch):
    """The check above can fail: a catalogue without one of base.html's msgids is reported."""
    po = i18n.po_path("zh").read_text(encoding="utf-8")
    gone = po.replace('msgstr "退出登录"', 'msgstr ""')
    assert gone != po
    (tmp_path / "zh" / "LC_MESSAGES").mkdir(parents=True)
    (tmp_path / "zh" / "LC_MESSAGES" / "messages.po").write_text(gone, encoding="utf-8")
    monkeypatch.setattr(i18n, "TRANSLATIONS_DIR", tmp_path)
    i18n.translations.cache_clear()
    try:
        assert "Sign out" in template_msgids("base.html") and "Sign out" not in i18n.known("zh")
    finally:
        monkeypatch.undo()
        i18n.translations.cache_clear()


def test_every_student_page_renders_in_chinese_with_nothing_untranslated(api):
    """Walks the student's pages in Chinese; every msgid and service message asked for on the way is translated."""
    i18n.MISSING.clear()
    aid = create(api).json()["id"]  # open checkpoints
    closed = create(api, title="Later", open_at=at(1), due_at=at(2), hard_close_at=at(3)).json()["id"]
    pages = {
        "sign-in": api.client.get("/sign-in", headers=ZH),
        "unknown link": api.client.get("/sign-in/link/nothing-like-this", headers=ZH),
        "course": api.client.get("/courses/l03", headers=zh(api)),
        "free sheet": api.client.get("/sheet", headers=zh(api)),
        "assignment sheet": api.client.get(f"/assignments/{aid}/sheet", headers=zh(api)),
        "not open sheet": api.client.get(f"/assignments/{closed}/sheet", headers=zh(api)),
        "not found": api.client.get("/submissions/999999", headers=zh(api)),
    }
    imported = import_yaml(api, REFERENCE_YAML.read_text(), path="/sheet")
    fields = form_fields(imported.text, **{"configs.table_exercise.dt": "0.02"})
    pages["checked"] = api.client.post("/sheet", headers=zh(api), data={**fields, "action": "check"})
    fields = form_fields(imported.text)
    pages["saved"] = api.client.post("/sheet", headers=zh(api), data={**fields, "action": "save"})
    refused = form_fields(pages["not open sheet"].text)
    pages["refused"] = api.client.post(f"/assignments/{closed}/sheet", headers=zh(api),
                                       data={**refused, "action": "submit"})
    sid = submit_from_form(api, "/sheet", fields, headers=zh(api))
    pages["report"] = api.client.get(f"/submissions/{sid}", headers=zh(api))
    pages["submissions"] = api.client.get("/submissions", headers=zh(api))
    for name, page in pages.items():
        assert page.status_code in (200, 404, 409), (name, page.status_code, page.text[:500])
        assert '<html lang="zh">' in page.text, name
        assert "Genesis 实验自动评分系统" in page.text, name
    assert "课程 l03" in pages["course"].text and "填写答题表" in pages["course"].text
    assert "现在不接受：" in pages["not open sheet"].text and "开放；现在是" in pages["not open sheet"].text
    assert "违反单因素规则" in pages["checked"].text and "不允许改动" in pages["checked"].text
    assert "草稿已保存。" in pages["saved"].text
    assert "无法识别此登录链接" in pages["unknown link"].text and "未找到" in pages["not found"].text
    assert f"提交 {sid}" in pages["report"].text and "案例运行" in pages["report"].text
    assert "你的提交记录" in pages["submissions"].text
    # The draft's messages for the page's script come in the page's language.
    assert 'data-msg-saved="草稿已保存 {when}"' in pages["free sheet"].text
    assert walk_missing() == set(), "asked for in Chinese but not translated"


def test_every_staff_page_renders_in_chinese_with_nothing_untranslated(api):
    """Walks the instructor's pages in Chinese (dashboard, set-up, assignment and its forms, rubric versions, tolerance
    review and draft, regrade preview, review queue, LTI admin); every msgid asked for on the way is translated."""
    from rubric.rubrics import rubric_versions

    i18n.MISSING.clear()
    prof = zh(api, "prof")
    aid = create(api).json()["id"]
    version = max(rubric_versions("L03"), key=lambda v: tuple(int(p) for p in str(v).split(".")))
    paths = {
        "dashboard": "/courses/l03/dashboard", "set-up": "/courses/l03/setup",
        "new assignment": "/courses/l03/setup/assignments/new", "assignment": f"/assignments/{aid}",
        "edit assignment": f"/assignments/{aid}/edit", "rubric versions": "/courses/l03/rubrics",
        "tolerance review": f"/courses/l03/rubrics/L03/{version}",
        "draft": f"/courses/l03/rubrics/L03/{version}/draft", "regrade": f"/courses/l03/regrade?version={version}",
        "reviews": "/courses/l03/reviews", "LTI admin": "/courses/l03/lti",
    }
    pages = {name: api.client.get(path, headers=prof) for name, path in paths.items()}
    for name, page in pages.items():
        assert page.status_code == 200, (name, page.status_code, page.text[:500])
        assert '<html lang="zh">' in page.text and "Genesis 实验自动评分系统" in page.text, name
    assert "课程设置：l03" in pages["set-up"].text and "设置时区" in pages["set-up"].text
    assert "学生名单" in pages["set-up"].text and "学习管理系统平台（LTI 1.3）" in pages["set-up"].text
    assert "计分的提交" in pages["new assignment"].text and "批准延期" in pages["assignment"].text
    assert "授课教师签核" in pages["tolerance review"].text and "新版本号" in pages["draft"].text
    assert "待处理（0）" in pages["reviews"].text and "立即重试" in pages["LTI admin"].text
    assert walk_missing() == set(), "asked for in Chinese but not translated"


def submit_from_form(api, path: str, fields: dict, headers: dict) -> int:
    """Submit through the form: the confirmation step, then its confirm button."""
    shown = api.client.post(path, headers=headers, data={**fields, "action": "submit"})
    assert shown.status_code == 200, shown.text[:1000]
    confirm = form_fields_of(shown.text, "confirm-form")
    done = api.client.post(path, headers=headers, data=confirm, follow_redirects=False)
    assert done.status_code == 303, done.text[:1000]
    return int(re.search(r"/submissions/([0-9]+)", done.headers["location"]).group(1))


def form_fields_of(page: str, form_id: str) -> dict[str, str]:
    form = re.search(rf'<form[^>]*id="{form_id}".*?</form>', page, re.S).group(0)
    return {m.group(1): html.unescape(m.group(2))
            for m in re.finditer(r'<input type="hidden" name="([^"]+)" value="([^"]*)"', form)}


@pytest.mark.clock("2026-12-10T00:00:00Z")  # the link below was used two days ago and expires in three weeks
def test_service_messages_are_translated_with_their_values():
    from grader.services.setup.assignments import late_text
    from grader.services.identity.sign_in_links import refusal

    late = late_text(26 * 3600 + 5 * 60)
    assert late == "1 d 2 h 5 min late (2 days charged)"
    assert i18n.message("zh", late) == "迟交 1 d 2 h 5 min（按 2 天计）"
    assert i18n.message("zh", late_text(0)) == "按时"
    course = SimpleNamespace(timezone="Asia/Shanghai")
    used = SimpleNamespace(user=SimpleNamespace(course=course), used_at=datetime(2026, 12, 8, 2, 0),
                           revoked_at=None, expires_at=datetime(2027, 1, 1))
    text = refusal(used)
    assert i18n.message("zh", text).startswith("此登录链接已于 2026-12-08 10:00 CST 使用过")
    assert i18n.message("zh", refusal(None)).startswith("无法识别此登录链接")
    assert i18n.message("en", text) == text  # English is the service's own text
    # A message no pattern knows stays English and is recorded for the translator.
    i18n.MISSING.clear()
    assert i18n.message("zh", "something new happened") == "something new happened"
    assert ("zh", "something new happened") in i18n.MISSING


@pytest.mark.clock("2026-12-10T00:00:00Z")
def test_dates_and_numbers_follow_the_locale(api):
    at_utc = datetime(2026, 12, 8, 2, 0)
    assert i18n.local_time(at_utc, "Asia/Shanghai", "en") == "2026-12-08 10:00 CST"
    assert i18n.local_time(at_utc, "Asia/Shanghai", "zh") == "2026年12月8日 10:00 CST"
    assert i18n.local_time(at_utc, "Europe/Berlin", "zh", seconds=True) == "2026年12月8日 03:00:00 CET"
    assert i18n.number(27.5, "zh") == "27.5" and i18n.number(30.0, "en") == "30" and i18n.number(1234.5, "en") == "1,234.5"
    assert i18n.percent(0.1, "zh") == "10%" and i18n.percent(0.125, "en") == "12.5%"
    create(api, late_penalty_per_day=0.1)
    page = api.client.get("/courses/l03", headers=zh(api)).text
    assert re.search(r"[0-9]{4}年[0-9]{1,2}月[0-9]{1,2}日 [0-9]{2}:[0-9]{2}", page)
    assert "每迟交一天（不足一天按一天计）扣 10%" in page
    english = api.client.get("/courses/l03", headers=api.as_("alice")).text
    assert re.search(r"[0-9]{4}-[0-9]{2}-[0-9]{2} [0-9]{2}:[0-9]{2}", english) and "10% per started day late" in english


def test_questions_are_translated_beside_the_rubric_and_no_published_version_changes(api):
    from rubric import load_rubric
    from rubric.rubrics import LESSONS_DIR, parse_rubric, rubric_versions

    table = i18n.lesson_text("L03", "zh")
    for version in rubric_versions("L03"):
        book = load_rubric("L03", version)
        assert [i.id for i in book.items if i.question not in table["questions"]] == [], version
        assert [r.description for r in book.configs.values() if r.description not in table["configs"]] == []
        # The published content, hence its hash, is the committed file's: the translations live beside it.
        committed = subprocess.run(["git", "show", f"HEAD:rubric/lessons/L03-v{version}.yaml"], cwd=ROOT,
                                   capture_output=True, text=True, check=True).stdout
        assert parse_rubric(yaml.safe_load(committed)).content_hash == book.content_hash
    assert "L03.zh.yaml" not in {p.name for p in LESSONS_DIR.glob("L03-v*.yaml")}
    aid = create(api).json()["id"]
    question = load_rubric("L03").item("C5").question
    chinese = api.client.get(f"/assignments/{aid}/sheet", headers=zh(api)).text
    assert html.escape(table["questions"][question]) in chinese and html.escape(question) not in chinese
    assert html.escape(question) in api.client.get(f"/assignments/{aid}/sheet", headers=api.as_("alice")).text
    # Every label and choice the form shows has its Chinese.
    from grader.services.submissions import sheet_form
    from rubric.sheet import Answers

    inputs = [i for item in Answers.model_fields
              for i in sheet_form.answer_inputs(Answers.model_fields[item].annotation, f"answers.{item}")]
    assert sorted({i.label for i in inputs} - set(table["labels"])) == []
    assert sorted({c.replace("_", " ") for i in inputs for c in i.choices} - set(table["choices"])) == []


def test_the_grade_never_depends_on_the_language_of_the_page(api, lesson_measured):
    """The same answers submitted from the Chinese and the English form are stored and graded identically."""
    from sqlalchemy import select

    from grader.core.db import new_session
    from grader.core.models import Grade, Submission
    from tests.grader.services.setup.test_assignments import checkpoint_sheet

    aid = create(api).json()["id"]
    graded = {}
    for who, headers in (("alice", zh(api, "alice")), ("bob", api.as_("bob"))):
        page = api.client.post(f"/assignments/{aid}/sheet/import", headers=headers, files={
            "file": ("s.yaml", yaml.safe_dump(checkpoint_sheet(who)).encode(), "application/yaml")})
        assert page.status_code == 200, page.text[:500]
        sid = submit_from_form(api, f"/assignments/{aid}/sheet", form_fields(page.text), headers=headers)
        with new_session() as session:
            sheet = session.get(Submission, sid).sheet
            grade = session.scalars(select(Grade).where(Grade.submission_id == sid)).one()
            graded[who] = ({**sheet, "student": None}, grade.total,
                           [(i["id"], i["verdict"], i["score"], i["feedback"]) for i in grade.report["items"]])
    assert graded["alice"] == graded["bob"]
    assert graded["alice"][1] > 0 and len(graded["alice"][2]) == 8
