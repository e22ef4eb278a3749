"""`--only bounded`: the worst sheet the caps admit (grader.services.submissions.sheets: every value the sheet may hold spent on
extra config keys the form shows as inputs, every explanation at its length limit) through the sheet form's check,
save, export, import and submit and the API's POST, on the app in-process (SQLite, nothing sent to a worker): each
must take a bounded time however the input is shaped (issue 31, item 3; target 0.2 s each)."""

from __future__ import annotations

import time
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urlencode

import yaml

from tools.bench.stats import median

TARGET_S = 0.2


def worst_sheet(reference: dict) -> dict:
    """The reference sheet with each explanation at its 4000 characters and the rest of the values budget spent on
    extra keys of the form's two configs, each a mapping of leaves (each leaf one form input and one more path for
    every per-key step), with every mapping at most MAX_KEYS wide."""
    from grader.services.submissions.sheets import MAX_KEYS, MAX_VALUES, size_problems

    sheet = yaml.safe_load(yaml.safe_dump(reference))
    for answer in sheet["answers"].values():
        answer["explanation"] = "x" * 4000

    def values(value) -> int:
        if isinstance(value, dict):
            return 1 + sum(values(v) for v in value.values())
        if isinstance(value, list):
            return 1 + sum(values(v) for v in value)
        return 1

    width = 15  # leaves per extra key: 16 values each
    budget = MAX_VALUES - values(sheet)
    roles = ("table_exercise", "extension")
    n = 0
    while budget >= width + 1:
        config = sheet["configs"][roles[n % 2]]
        if len(config) >= MAX_KEYS:
            if all(len(sheet["configs"][r]) >= MAX_KEYS for r in roles):
                break
            n += 1
            continue
        config[f"extra{n}"] = {f"f{j}": j * 0.5 for j in range(width)}
        budget -= width + 1
        n += 1
    assert not size_problems(sheet), size_problems(sheet)
    return sheet


class _FormFields(HTMLParser):
    """What a browser posts from the page's sheet form: each named input's value (checked ones only)."""

    def __init__(self):
        super().__init__()
        self.fields: dict[str, list[str]] = {}
        self._form = False
        self._select = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "form":
            self._form = a.get("id") == "sheet-form"
        elif not self._form:
            return
        elif tag == "input" and a.get("name") and a.get("type") != "file":
            if a.get("type") not in ("radio", "checkbox") or "checked" in a:
                self.fields.setdefault(a["name"], []).append(a.get("value") or "")
        elif tag == "select":
            self._select = a.get("name")
        elif tag == "option" and self._select and "selected" in a:
            self.fields.setdefault(self._select, []).append(a.get("value") or "")
        elif tag == "textarea" and a.get("name"):
            self.fields.setdefault(a["name"], []).append("x" * 4000)

    def handle_endtag(self, tag):
        if tag == "select":
            self._select = None
        elif tag == "form":
            self._form = False


def _timed(call, repeats: int) -> tuple[float, float, object]:
    """Median wall seconds and median CPU seconds of this process (the app runs in it: on a shared machine the CPU
    figure is the work itself, the wall figure adds the wait for a core), and the last answer."""
    seconds, cpu, last = [], [], None
    for _ in range(repeats):
        started, started_cpu = time.perf_counter(), time.process_time()
        last = call()
        seconds.append(time.perf_counter() - started)
        cpu.append(time.process_time() - started_cpu)
    return median(seconds), median(cpu), last


def bench_bounded(out_dir: Path, repeats: int, *, log) -> dict:
    """Median seconds of each action on the worst admitted sheet, with the status each answered."""
    import os

    from fastapi.testclient import TestClient
    from sqlalchemy.orm import Session

    from grader import dispatch
    from grader.core import db
    from grader.services.identity import accounts, quotas
    from grader.core.settings import settings
    from tools.bench.submission import reference_sheet

    out_dir.mkdir(parents=True, exist_ok=True)
    url = f"sqlite:///{(out_dir / f'bounded-{os.getpid()}.db').absolute()}"
    kept = settings.model_copy()
    sends = dispatch.send_case_run, dispatch.send_grade
    settings.database_url, settings.artifacts_dir = url, out_dir / "artifacts"
    for rule in ("rate_limit_submissions", "rate_limit_draft_saves"):
        setattr(settings, rule, "100000/minute")
    settings.student_waiting_runs_max = 100_000
    db._engine = None
    db.migrate(url)
    with Session(db.get_engine()) as session:
        course = accounts.get_or_create_course(session=session, name="bench")
        student = accounts.get_or_create_user(session=session, course=course, name="ada", role="student")
        token = accounts.create_token(session=session, user=student)
        session.commit()
    quotas._limiter.cache_clear()
    dispatch.send_case_run = lambda *args, **kw: None  # measured: the service's work, not a broker's
    dispatch.send_grade = lambda *args, **kw: None
    from grader.main import app

    client = TestClient(app, headers={"Authorization": f"Bearer {token}"})
    sheet = worst_sheet(reference_sheet() | {"student": "ada"})
    text = yaml.safe_dump(sheet, sort_keys=False)
    imported = client.post("/sheet/import", files={"file": ("sheet.yaml", text.encode(), "application/yaml")})
    assert imported.status_code == 200, imported.text[:500]
    parser = _FormFields()
    parser.feed(imported.text)
    fields = parser.fields
    posted = sum(len(v) for v in fields.values())
    figures = {"repeats": repeats, "yaml_bytes": len(text.encode()), "form_fields": posted,
               "config_inputs": sum(1 for name in fields if name.startswith("configs.")), "actions": {}}
    form = {"content-type": "application/x-www-form-urlencoded"}

    def pressed(action: str) -> bytes:  # encoded once: the figure is the server's work, not the client's encoding
        return urlencode([(k, v) for k, values in fields.items() for v in values] + [("action", action)]).encode()

    bodies = {action: pressed(action) for action in ("save", "check", "export", "submit")}
    actions = {
        "import": lambda: client.post("/sheet/import", files={"file": ("s.yaml", text.encode(), "application/yaml")}),
        "save": lambda: client.post("/sheet", content=bodies["save"], headers=form),
        "check": lambda: client.post("/sheet", content=bodies["check"], headers=form),
        "export": lambda: client.post("/sheet", content=bodies["export"], headers=form),
        "submit (form)": lambda: client.post("/sheet", content=bodies["submit"], headers=form),
        "submit (API)": lambda: client.post("/v1/submissions", json={"sheet": sheet}),
    }
    for name, call in actions.items():
        seconds, cpu, answer = _timed(call, repeats)
        figures["actions"][name] = {"median_s": seconds, "cpu_s": cpu, "status": answer.status_code}
        log(f"  {name:14s} {seconds:6.3f} s wall, {cpu:6.3f} s CPU  ({answer.status_code})")
    db.get_engine().dispose()
    db._engine = None
    for name in type(settings).model_fields:  # the rest of the run sees the settings it started with
        setattr(settings, name, getattr(kept, name))
    dispatch.send_case_run, dispatch.send_grade = sends
    quotas._limiter.cache_clear()
    return figures


def format_bounded(f: dict) -> list[str]:
    lines = [f"the worst sheet the caps admit ({f['yaml_bytes'] / 1024:.0f} KB of YAML, {f['config_inputs']} config "
             f"inputs, {f['form_fields']} form fields), in-process, median of {f['repeats']} (wall / CPU):"]
    for name, row in f["actions"].items():
        ok = "met" if row["median_s"] <= TARGET_S else f"MISSED ({row['median_s'] / TARGET_S:.1f}x)"
        lines.append(f"  {name:14s} {row['median_s']:7.3f} s / {row['cpu_s']:6.3f} s  answered {row['status']}   "
                     f"{ok} (<= {TARGET_S} s wall)")
    return lines
