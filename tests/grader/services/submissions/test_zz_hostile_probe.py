"""Hostile probes (1): sibling assignment, events, gradescope, ETag across a due date."""
from __future__ import annotations

import html
import json
import re

import pytest

from tests.grader.services.setup.test_assignments import at, create, submit, checkpoint_sheet
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401
from tests.grader.services.submissions.test_integrity_withholding import grade_of


def _get(api, path, who="alice", **headers):
    return api.client.get(path, headers={**api.as_(who), **headers})


def test_sibling_assignment_shows_what_other_withholds(api, lesson_measured):
    exam = create(api, title="Exam", visibility="on_release").json()["id"]   # C1..C8 withheld until release
    practice = create(api, title="Practice").json()["id"]                     # immediate
    r = submit(api, practice)
    print("submit practice", r.status_code)
    sid = r.json()["id"]
    g = grade_of(api, sid, "alice")
    print("grade alice practice", g.status_code)
    items = {i["id"]: i for i in g.json()["items"]}
    for i, it in items.items():
        print(i, it["verdict"], it["score"], "| expected:", it["expected"][:80], "| fb:", it["feedback"][:100])
    print("withheld_measurements", g.json()["withheld_measurements"])
    r2 = submit(api, exam)
    sid2 = r2.json()["id"]
    g2 = grade_of(api, sid2, "alice")
    print("exam grade", g2.status_code, g2.text[:300])
    # free submission of the checkpoints
    r3 = api.client.post("/v1/submissions", json={"sheet": checkpoint_sheet()}, headers=api.as_("alice"))
    print("free", r3.status_code, r3.text[:200])
    if r3.status_code == 202:
        g3 = grade_of(api, r3.json()["id"], "alice")
        print("free grade", g3.status_code, g3.text[:300])
    ev = _get(api, f"/v1/submissions/{sid}/events").json()
    print("events", json.dumps(ev)[:1500])


def test_gradescope_of_checkpoint_while_b3_withheld(api, lesson_measured):
    create(api, title="Exercises", part="exercises", item_visibility={"B3": "on_release"})
    cp = create(api).json()["id"]
    sid = submit(api, cp).json()["id"]
    for who in ("alice",):
        for p in (f"/v1/submissions/{sid}/gradescope.json", f"/submissions/{sid}/gradescope.json"):
            r = _get(api, p, who)
            print(who, p, r.status_code, r.text[:200])
    gs = _get(api, f"/v1/submissions/{sid}/gradescope.json", "prof").json()
    for t in gs["tests"]:
        print("GS", t["name"][:4], t["visibility"], "|", t["output"][:300].replace("\n", " / "))
    staff = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}
    print("staff C5 measured", staff["C5"]["measured"], staff["C5"]["backends"])
    mine = {i["id"]: i for i in grade_of(api, sid, "alice").json()["items"]}
    print("alice C5", mine["C5"]["feedback"])
