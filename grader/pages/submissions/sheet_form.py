"""A student's prediction sheet as a form (grader.services.submissions.sheet_form), for one assignment or their free sheet: the
draft kept on the server, checked by the submission's own rules, imported from and exported to the API's YAML, and
submitted through the same service as the API's POST. For the course's students and instructors; anyone else gets
the not-found page. A student at an assignment with a variant pool fills the form of their own lab (its parameters
at the top, its numbers in the questions, its baseline in the config editor and the one-factor check); until the pool
is ready the page says the lab is being prepared."""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import APIRouter, Depends, File, Request, UploadFile, status
from fastapi.responses import HTMLResponse, PlainTextResponse, RedirectResponse, Response
from starlette.datastructures import FormData

from grader import dispatch
from grader import i18n
from grader.i18n import N_
from grader.web.deps import SessionDep
from grader.web.errors import status_of, with_retry_after
from grader.core.rubrics import course_rubric
from grader.core.models import Assignment, User, utcnow
from grader.pages.auth import SignedIn
from grader.pages.templates import TEMPLATES, request_locale
from grader.services.setup import assignments
from grader.services.submissions import drafts, sheets, submit as submissions
from grader.services.submissions import sheet_form as form_logic
from grader.services.errors import Conflict, DomainError, Invalid, NotFound, Refused
from grader.services.identity import access
from rubric import Variant
from rubric.variants import texts

router = APIRouter(include_in_schema=False)
# A sheet's YAML is a few kilobytes; the app's body limit (BodyGuard) bounds the upload before this does.
YAML_MAX_BYTES = 256 * 1024


def _writer(user: SignedIn) -> User:
    """Students and instructors fill sheets (the roles that may submit); an auditor gets the not-found page."""
    if not (access.is_student(user) or access.is_instructor(user)):
        raise NotFound("sheet form")
    return user


Writer = Annotated[User, Depends(_writer)]


def _members_assignment(assignment_id: int, session: SessionDep, user: Writer) -> Assignment:
    return assignments.assignment_of(session=session, user=user, assignment_id=assignment_id)


MembersAssignment = Annotated[Assignment, Depends(_members_assignment)]


async def _posted_form(request: Request) -> FormData:
    """The posted fields, all text: a file part where the form has a text input is refused naming the field (422).
    Read here, in the event loop, so that the handlers stay plain functions on the thread pool, as every page's."""
    form = await request.form()
    files = [name for name, value in form.multi_items() if not isinstance(value, str)]
    if files:
        raise Invalid("invalid form", [{"field": name, "rule": "must be text, not a file"} for name in files[:20]])
    return form


Posted = Annotated[FormData, Depends(_posted_form)]


def _path(assignment: Assignment | None) -> str:
    return f"/assignments/{assignment.id}/sheet" if assignment is not None else "/sheet"


def _part_and_lesson(assignment: Assignment | None) -> tuple[str, str]:
    """The items an assignment holds and its lesson; a free sheet answers every item of the one lesson."""
    return (assignment.part, assignment.lesson) if assignment is not None else ("sheet", form_logic.LESSON)


def _starting_sheet(user: User) -> dict:
    return {"lesson": form_logic.LESSON, "student": user.name, "answers": {}}


def _draft_sheet(session, user: User, assignment: Assignment | None) -> dict:
    draft = drafts.load(session=session, user=user, assignment=assignment)
    return draft.sheet if draft is not None else _starting_sheet(user)


def _standing(session, user: User, assignment: Assignment | None) -> dict | None:
    """What a submission now would be: its attempt, lateness and penalty, or the rule that refuses it."""
    if assignment is None:
        return None
    try:
        attempt, late = assignments.admit(session=session, assignment=assignment, student=user, now=utcnow())
    except Refused as exc:  # the page words it from exc.reason and exc.facts (templates/_refusal.html)
        return {"refused": exc}
    return {"attempt": attempt, "late": assignments.late_text(late),
            "penalty": assignments.penalty_fraction(assignment, late)}


def _variant(session, user: User, assignment: Assignment | None) -> Variant | None:
    """The student's own variant of the assignment (form_logic.form_variant: fixed at this first view), read once per
    request; None for a free sheet, staff and an assignment without a pool. Conflict while its pool is not ready."""
    variants = session.info.setdefault("sheet_form_variants", {})
    key = (user.id, assignment.id if assignment is not None else None)
    if key not in variants:
        variants[key] = form_logic.form_variant(session=session, assignment=assignment, user=user)
    return variants[key]


def _preparing(request: Request, user: User, assignment: Assignment, code: int = status.HTTP_200_OK) -> HTMLResponse:
    """The page of an assignment whose lab (its variant pool) is still being measured: no form, no parameters yet."""
    return TEMPLATES.TemplateResponse(request, "submissions/sheet_form.html", {
        "user": user, "a": assignment, "preparing": True, "path": _path(assignment)}, status_code=code)


def _book(session, user: User, lesson: str):
    """The course's rubric, read once per request (its session): a post both reads the form and renders the page."""
    books = session.info.setdefault("sheet_form_books", {})
    if (user.course_id, lesson) not in books:
        books[user.course_id, lesson] = course_rubric(session, user.course_id, lesson)
    return books[user.course_id, lesson]


# --- the config editor: each field in words, its unit, and whether the lesson lets it change --------------------------

# A config field's words and unit by its path, digits as "#" (`lanes.#.color.#`): msgids with %(axis)s, %(lane)s
# (counted from 1) and %(channel)s put in on the page.
CONFIG_LABELS: dict[str, tuple[str, str]] = {
    "name": (N_("config name"), ""),
    "dt": (N_("outer time step dt"), "s"),
    "substeps": (N_("substeps per outer step"), ""),
    "duration": (N_("simulated duration"), "s"),
    "gravity.#": (N_("gravity %(axis)s"), "m/s²"),
    "enable_collision": (N_("collisions enabled"), ""),
    "table.size.#": (N_("table size %(axis)s"), "m"),
    "table.pos.#": (N_("table centre %(axis)s"), "m"),
    "table.friction": (N_("table friction"), ""),
    "cube.size": (N_("cube edge"), "m"),
    "cube.pos.#": (N_("cube start %(axis)s"), "m"),
    "cube.rho": (N_("cube density"), "kg/m³"),
    "cube.friction": (N_("cube friction"), ""),
    "cube.color.#": (N_("cube colour, %(channel)s"), ""),
    "separation_tolerance": (N_("separation tolerance"), "m"),
    "upward_speed_tolerance": (N_("upward speed tolerance"), "m/s"),
    "tail_window": (N_("tail window"), "s"),
    "cube_size": (N_("cube edge"), "m"),
    "cube_rho": (N_("cube density"), "kg/m³"),
    "start_x": (N_("start x"), "m"),
    "lanes.#.name": (N_("lane %(lane)s name"), ""),
    "lanes.#.friction": (N_("lane %(lane)s cube friction"), ""),
    "lanes.#.y": (N_("lane %(lane)s y"), "m"),
    "lanes.#.color.#": (N_("lane %(lane)s colour, %(channel)s"), ""),
    "settle_steps": (N_("settling steps before measuring"), ""),
    "initial_speed": (N_("initial speed"), "m/s"),
    "stop_speed": (N_("stop speed threshold"), "m/s"),
    "hold": (N_("stop hold time"), "s"),
    "seed": (N_("random seed"), ""),
    "precision": (N_("floating-point precision"), "bits"),
}
AXES = ("x", "y", "z")
# Held fields that are no physics of the experiment: shown after those that are.
LAST_HELD = ("name", "seed", "precision")
CHANNELS = (N_("red"), N_("green"), N_("blue"))
# Fields the one-factor rule never counts (rubric.specs.IGNORED_FIELDS and the visual layer): free to change.
UNCOUNTED = re.compile(r"^(name|render|cube\.color(\.[0-9]+)?|lanes\.[0-9]+\.color(\.[0-9]+)?)$")


@dataclass(frozen=True)
class ConfigField:
    """One config input as the editor shows it: its words (a msgid and what goes into it), unit, baseline value, and
    whether the lesson lets it change (else it is held fixed), or the rule never counts it (a colour, the name)."""

    input: form_logic.Input
    label: str
    params: dict
    unit: str
    baseline: str
    changeable: bool
    counted: bool

    @property
    def name(self) -> str:
        return self.input.name


def _config_field(book, role: str, field: form_logic.Input) -> ConfigField:
    path = field.label  # the input's path within its config
    digits = [int(d) for d in re.findall(r"(?<=\.)[0-9]+(?=\.|$)", path)]
    pattern = re.sub(r"(?<=\.)[0-9]+(?=\.|$)", "#", path)
    label, unit = CONFIG_LABELS.get(pattern, (path, ""))
    params: dict[str, Any] = {}
    if pattern.startswith("lanes.#"):
        params["lane"] = digits.pop(0) + 1
    if digits and pattern.endswith("color.#"):
        params["channel"] = CHANNELS[digits[0]] if digits[0] < 3 else str(digits[0])
    elif digits:
        params["axis"] = AXES[digits[0]] if digits[0] < 3 else str(digits[0])
    baseline = "" if field.default is None else form_logic.form_text(field.default)
    return ConfigField(field, label, params, unit, baseline, form_logic.may_change(book, role, path),
                       UNCOUNTED.match(path) is None)


def _config_fields(book, role: str, sheet: dict, variant: Variant | None = None) -> list[ConfigField]:
    """The role's config fields (their baseline the variant's when given), those the lesson lets change first (in the
    rule's order), then the held ones."""
    fields = [_config_field(book, role, f) for f in form_logic.config_inputs(book, role, sheet, variant)]
    order = book.configs[role].may_change
    first = sorted((f for f in fields if f.changeable),
                   key=lambda f: next((n for n, m in enumerate(order) if f.input.label == m
                                       or f.input.label.startswith(m + ".")), len(order)))
    held = [f for f in fields if not f.changeable]
    return first + sorted(held, key=lambda f: f.input.label in LAST_HELD)  # stable: the physics first, as declared


def _held_changed(fields: list[ConfigField], values: dict) -> bool:
    """Whether a counted held field differs from its baseline as the draft stands."""
    return any(not f.changeable and f.counted and f.input.default is not None
               and values.get(f.name) != f.baseline for f in fields)


# --- refusals in the reader's words -----------------------------------------------------------------------------------

# Fields a refusal names that the page words by its rule alone: the assignment (its title is in the rule) and the
# per-person quotas (the rule says which).
UNLABELLED = ("assignment_id", "submissions", "draft", "draft saves")


def _field_label(field: str, items, configs: dict[str, list[ConfigField]], gettext, lesson_word
                 ) -> tuple[str, str, str]:
    """(words, input id, the rest of the path no input names) of the field an error names: `answers.A2.direction`
    -> ("A2 direction", its first input, ""); a key inside a config that no input shows -> its config's words, the
    config's section and the key (`a.b`)."""
    path = field.removeprefix("sheet.")
    if path in UNLABELLED:
        return "", "", ""
    if path in ("student", "file"):
        words = {"student": gettext(N_("student (your name on the sheet)")), "file": gettext(N_("YAML file"))}[path]
        return words, {"student": "f-student", "file": "yaml-file"}[path], ""
    for item in items:
        for i in item.inputs:
            if path == i.name or path.startswith(i.name + "."):
                anchor = f"f-{i.name}.value" if i.widget in ("quantity", "stop") else f"f-{i.name}"
                return f"{item.id} {lesson_word('labels', i.label)}", anchor, ""
        if path == f"answers.{item.id}" or path.startswith(f"answers.{item.id}."):
            return item.id, f"item-{item.id}", path.removeprefix(f"answers.{item.id}").lstrip(".")
    for role, fields in configs.items():
        for f in fields:
            if path == f.name or path.startswith(f.name + "."):
                label = gettext(f.label, **{k: gettext(v) if k == "channel" else v for k, v in f.params.items()})
                return f"{lesson_word('roles', role.replace('_', ' '))}: {label}", f"f-{f.name}", ""
        if path == f"configs.{role}" or path.startswith(f"configs.{role}."):
            return (lesson_word("roles", role.replace("_", " ")), f"config-{role}",
                    path.removeprefix(f"configs.{role}").lstrip("."))
    return "", "", path


def _words(request: Request, variant: Variant | None = None):
    """The request's gettext for a page module's own words: `say(msgid, **values)`, and the lesson's words (an answer
    label as a student on `variant` reads it, with their numbers)."""
    locale = request_locale(request)

    def say(msgid: str, **values) -> str:
        text = i18n.gettext(locale, msgid)
        return text % values if values else text

    def lesson_word(section: str, text: str) -> str:
        if variant is not None and section == "labels":
            return form_logic.answer_label(text, variant, locale)
        return i18n.lesson_word(locale, section, text)

    return say, lesson_word


def _summary(request: Request, items, configs: dict[str, list[ConfigField]], errors: list[dict], checks: list,
             refusal: DomainError | None, checked: bool, variant: Variant | None = None) -> dict | None:
    """What the top of the page says after Check or a refused Submit: each error with its field's words and a link
    to its input, each config's verdict with the items it voids, and whether the sheet passes every rule (only when
    nothing is wrong and no config breaks the one-factor rule)."""
    if not checked and refusal is None:
        return None
    say, lesson_word = _words(request, variant)
    rows, seen = [], set()
    for error in errors:
        if (error["field"], error["rule"]) in seen:  # each message once
            continue
        seen.add((error["field"], error["rule"]))
        words, anchor, rest = _field_label(error["field"], items, configs, say, lesson_word)
        # the assignment's own refusal is worded from its reason and facts (templates/_refusal.html), the rest as written
        own = refusal if (refusal is not None and refusal.reason and error["field"] == getattr(refusal, "field", None)
                          and error["rule"] == getattr(refusal, "rule", None)) else None
        rows.append({"label": words, "href": anchor, "code": rest, "rule": error["rule"], "refusal": own})
    broken = [c for c in checks if c.violations]
    return {"errors": rows, "checks": checks, "broken": broken,
            "detail": refusal.detail if refusal is not None and not rows else None,
            "passes": checked and refusal is None and not rows and not broken}


def _render(request: Request, session, user: User, assignment: Assignment | None, sheet: dict, *,
            errors: list[dict] | None = None, checked: bool = False, notice: str | None = None,
            refusal: DomainError | None = None, code: int = status.HTTP_200_OK,
            unlock: str | None = None, submitting: bool = False) -> HTMLResponse:
    part, lesson = _part_and_lesson(assignment)
    try:
        variant = _variant(session, user, assignment)
    except Conflict:  # the pool is still being measured: no form until the student's lab is known
        return _preparing(request, user, assignment)
    locale = request_locale(request)
    if too_large := sheets.size_problems(sheet):  # a draft saved before the caps held: never rendered input by input
        refusal = refusal or Invalid(OVER_CAPS, too_large)
        errors, sheet = refusal.errors, _starting_sheet(user)
    book = _book(session, user, lesson)
    ids = assignments.item_ids(lesson, part)
    items = form_logic.item_forms(book, ids, variant, locale)
    book_configs = book if form_logic.has_configs(part) else None
    configs = ({role: _config_fields(book, role, sheet, variant) for role in form_logic.form_configs(book)}
               if book_configs else {})
    checks = []
    if checked and book_configs is not None:
        checks, config_errors = form_logic.config_checks(session=session, sheet=sheet, part=part, book=book,
                                                         variant=variant)
        shown = {(e["field"], e["rule"]) for e in errors or []}  # a set: one pass, whatever the number of errors
        errors = (errors or []) + [e for e in config_errors if (e["field"], e["rule"]) not in shown]
    names = (["file", "student"] + [i.name for item in items for i in item.inputs]
             + [f.name for fields in configs.values() for f in fields])
    placed, unplaced = form_logic.by_input(errors or [], names)
    extra_roles = sorted(set((sheet.get("configs") or {}) if isinstance(sheet.get("configs"), dict) else ())
                         - set(form_logic.form_configs(book)))
    values = form_logic.form_state(sheet, items, book_configs, variant)
    # A role's held fields are editable when asked for (the "change a held field" button without the script), when
    # the draft already changed one, or when an error sits in one.
    changed_roles = {role for role, fields in configs.items() if _held_changed(fields, values)}
    unlocked = changed_roles | {role for role, fields in configs.items()
                                if role == unlock or any(not f.changeable and f.name in placed for f in fields)}
    voids = (form_logic.held_voids(session=session, sheet=sheet, part=part, book=book, variant=variant)
             if book_configs is not None else {})
    standing = _standing(session, user, assignment)
    summary = _summary(request, items, configs, errors or [], checks, refusal, checked, variant)
    # A student's own lab: its parameters said once at the top, A1's labels and the configs' rules with its numbers.
    lab = None if variant is None else {
        "summary": texts.parameter_summary(variant, locale),
        "label": lambda text: form_logic.answer_label(text, variant, locale),
        "rules": {role: texts.config_description(book, role, variant, locale) for role in configs},
    }
    return TEMPLATES.TemplateResponse(request, "submissions/sheet_form.html", {
        "user": user, "a": assignment, "part": part, "lesson": lesson, "path": _path(assignment), "items": items,
        "configs": configs, "rules": {role: book.configs[role] for role in configs}, "extra_roles": extra_roles,
        "values": values, "placed": placed, "unplaced": unplaced, "unlocked": unlocked, "voids": voids,
        "changed_roles": changed_roles, "submitting": submitting, "lab": lab,
        "checked": checked, "checks": checks, "notice": notice, "refusal": refusal, "summary": summary,
        # the rule that refuses a submission now, said once: in the summary when a Submit was refused by it
        "standing": standing,
        "standing_shown": not (refusal is not None and standing and standing.get("refused")
                               and any(e.get("field") == "assignment_id" for e in refusal.errors)),
        "has_last": drafts.last_submitted(session=session, user=user, assignment=assignment) is not None,
    }, status_code=code)


OVER_CAPS = "your saved draft cannot be edited in the form; import a corrected YAML"


def _posted_sheet(session, user: User, assignment: Assignment | None, form) -> dict:
    """The sheet the posted form holds over the saved draft. Invalid naming the path when the saved draft is past the
    caps (grader.services.submissions.sheets.size_problems: one saved before they held, or a key the form cannot name): a YAML
    import, or starting from the last submission, replaces it."""
    part, lesson = _part_and_lesson(assignment)
    book = _book(session, user, lesson)
    items = form_logic.item_forms(book, assignments.item_ids(lesson, part))
    previous = _draft_sheet(session, user, assignment)
    sheets.check_size(previous, detail=OVER_CAPS)
    sheet = form_logic.sheet_from_form(form, items=items, book=book if form_logic.has_configs(part) else None,
                                       previous=previous, variant=_variant(session, user, assignment))
    sheet["lesson"] = lesson
    return sheet


def sheet_digest(sheet: dict) -> str:
    """Names the exact draft a confirmation showed, so that "Submit attempt N" submits that draft and no other."""
    return hashlib.sha256(json.dumps(sheet, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:24]


def _precheck(session, user: User, assignment: Assignment | None, sheet: dict) -> DomainError | None:
    """The refusals a submission now would meet, in the service's order (the assignment's rules, then the sheet's);
    what only submitting can tell (a staff power, a queue's cap) the confirmed submit still answers."""
    if assignment is not None:
        try:
            assignments.admit(session=session, assignment=assignment, student=user, now=utcnow())
        except Refused as exc:
            return exc
    part, _ = _part_and_lesson(assignment)
    problems = form_logic.problems(sheet, part)
    return Invalid("invalid sheet", problems) if problems else None


def _config_verdicts(session, assignment: Assignment | None, user: User, sheet: dict) -> list:
    """The one-factor verdict of each of the sheet's configs, with the items each broken one voids (the Check's)."""
    part, lesson = _part_and_lesson(assignment)
    if not form_logic.has_configs(part):
        return []
    checks, _ = form_logic.config_checks(session=session, sheet=sheet, part=part,
                                         book=_book(session, user, lesson),
                                         variant=_variant(session, user, assignment))
    return checks


def _confirmation(request: Request, session, user: User, assignment: Assignment | None, sheet: dict, *,
                  notice: str | None = None, missing_consent: bool = False) -> HTMLResponse:
    """The step between the form and the submission: the attempt it will be, how late, the penalty, any config the
    one-factor rule voids (with the items; submitting then takes an explicit second confirmation), and the two ways
    on (submit this draft, or back to the form with the draft kept)."""
    part, lesson = _part_and_lesson(assignment)
    standing = _standing(session, user, assignment)
    checks = _config_verdicts(session, assignment, user, sheet)
    return TEMPLATES.TemplateResponse(request, "submissions/submit_confirm.html", {
        "user": user, "a": assignment, "part": part, "lesson": lesson, "path": _path(assignment),
        "standing": standing,
        "digest": sheet_digest(sheet), "notice": notice,
        "questions": len(assignments.item_ids(lesson, part)), "broken": [c for c in checks if c.violations],
        "missing_consent": missing_consent,
    }, status_code=status.HTTP_422_UNPROCESSABLE_ENTITY if missing_consent else status.HTTP_200_OK)


# The confirmation's checkbox a student ticks to submit configs the one-factor rule voids.
CONSENT = "accept_voids"


def _confirmed(request: Request, session, user: User, assignment: Assignment | None, form: FormData) -> Response:
    """Submit the saved draft the confirmation named; a draft or attempt changed since is confirmed again, and a
    draft whose configs break the one-factor rule only with the confirmation's second tick (else it is shown again,
    the tick named, the draft kept)."""
    sheet = _draft_sheet(session, user, assignment)
    standing = _standing(session, user, assignment)
    if form.get("digest") != sheet_digest(sheet):
        return _confirmation(request, session, user, assignment, sheet, notice=N_(
            "Your draft changed after this confirmation was shown (another tab or window saved it): "
            "here is the draft as it is now."))
    if standing and standing.get("attempt") and str(standing["attempt"]) != form.get("attempt"):
        return _confirmation(request, session, user, assignment, sheet, notice=N_(
            "Another submission was made meanwhile: this one would now take the attempt named below."))
    if form.get(CONSENT) != "yes" and any(c.violations for c in _config_verdicts(session, assignment, user, sheet)):
        return _confirmation(request, session, user, assignment, sheet, missing_consent=True)
    try:
        submission = submissions.submit(session=session, user=user, sheet=sheet,
                                        assignment_id=assignment.id if assignment else None, sender=dispatch)
    except NotFound:
        raise
    except DomainError as exc:  # the rule beside the form; the draft stays as it was
        session.rollback()
        return with_retry_after(_render(request, session, user, assignment, sheet, errors=exc.errors, refusal=exc,
                                        code=status_of(exc), checked=True, submitting=True), exc)
    return RedirectResponse(f"/submissions/{submission.id}/progress", status_code=status.HTTP_303_SEE_OTHER)


def _act(request: Request, session, user: User, assignment: Assignment | None, form: FormData) -> Response:
    try:
        _variant(session, user, assignment)
    except Conflict:  # nothing is saved or submitted before the student's lab is known
        return _preparing(request, user, assignment, code=status.HTTP_409_CONFLICT)
    action = form.get("action") or "save"
    if action == "confirm":  # the confirmation's form carries no answers: it submits the saved draft
        return _confirmed(request, session, user, assignment, form)
    if action == "from_last":
        last = drafts.last_submitted(session=session, user=user, assignment=assignment)
        if last is None:
            raise NotFound("your last submission")
        drafts.save(session=session, user=user, assignment=assignment, sheet=last.sheet)
        return _render(request, session, user, assignment, last.sheet,
                       notice=f"The draft now holds your submission {last.id}'s sheet.")
    sheet = None
    try:
        sheet = _posted_sheet(session, user, assignment, form)
        drafts.save(session=session, user=user, assignment=assignment, sheet=sheet)
    except Invalid as exc:  # past a cap or the saves' quota: the rule above the form, the saved draft as it was
        session.rollback()
        shown = sheet if sheet is not None else _draft_sheet(session, user, assignment)
        return with_retry_after(_render(request, session, user, assignment, shown, errors=exc.errors, refusal=exc,
                                        code=status_of(exc)), exc)
    part, _ = _part_and_lesson(assignment)
    if action == "export":
        name = f"sheet-{assignment.id}.yaml" if assignment is not None else "sheet.yaml"
        return PlainTextResponse(form_logic.sheet_yaml(sheet), media_type="application/yaml",
                                 headers={"Content-Disposition": f'attachment; filename="{name}"'})
    if action == "check":  # the summary at the top says whether it passes every rule
        return _render(request, session, user, assignment, sheet, errors=form_logic.problems(sheet, part),
                       checked=True)
    if action.startswith("unlock:"):  # "change a held field" without the page's script: the same form, editable
        return _render(request, session, user, assignment, sheet, unlock=action.removeprefix("unlock:"))
    if action == "submit":  # first the confirmation; a submission it would refuse says the rule beside the form
        refusal = _precheck(session, user, assignment, sheet)
        if refusal is not None:
            return with_retry_after(_render(request, session, user, assignment, sheet, errors=refusal.errors,
                                            refusal=refusal, code=status_of(refusal), checked=True,
                                            submitting=True), refusal)
        return _confirmation(request, session, user, assignment, sheet)
    return _render(request, session, user, assignment, sheet, notice="Draft saved.")


def _save_draft(request: Request, session, user: User, assignment: Assignment | None, form: FormData) -> Response:
    """The page's script saves as the student types; no page comes back, only when it was saved: in the course's
    time zone, as the reader's locale writes times."""
    sheet = _posted_sheet(session, user, assignment, form)
    draft = drafts.save(session=session, user=user, assignment=assignment, sheet=sheet)
    when = i18n.local_time(draft.updated_at, user.course.timezone, request_locale(request), seconds=True)
    return PlainTextResponse(f"saved {when}")


def _import(request: Request, session, user: User, assignment: Assignment | None, file: UploadFile) -> Response:
    data = file.file.read(YAML_MAX_BYTES + 1)
    if len(data) > YAML_MAX_BYTES:
        exc = Invalid("invalid YAML", [{"field": "file", "rule": f"at most {YAML_MAX_BYTES} bytes"}])
    else:
        try:
            sheet = form_logic.sheet_from_yaml(data.decode("utf-8"))
            exc = None
        except UnicodeDecodeError:
            exc = Invalid("invalid YAML", [{"field": "file", "rule": "must be UTF-8 text"}])
        except Invalid as refused:
            exc = refused
    if exc is None:
        try:
            drafts.save(session=session, user=user, assignment=assignment, sheet=sheet)
        except Invalid as refused:  # the saves' quota
            session.rollback()
            exc = refused
    if exc is not None:  # the draft stays as it was
        return with_retry_after(_render(request, session, user, assignment, _draft_sheet(session, user, assignment),
                                        errors=exc.errors, refusal=exc, code=status_of(exc)), exc)
    return _render(request, session, user, assignment, sheet,
                   notice=f"Imported {file.filename or 'the file'} into the draft; check it before submitting.")


@router.get("/assignments/{assignment_id}/sheet", response_class=HTMLResponse)
def assignment_sheet(request: Request, assignment: MembersAssignment, session: SessionDep, user: Writer):
    return _render(request, session, user, assignment, _draft_sheet(session, user, assignment))


@router.post("/assignments/{assignment_id}/sheet", response_class=HTMLResponse)
def assignment_sheet_action(request: Request, assignment: MembersAssignment, session: SessionDep, user: Writer,
                            form: Posted):
    """Save, check, export (YAML), start from the last submission, or submit the form (after its confirmation)."""
    return _act(request, session, user, assignment, form)


@router.post("/assignments/{assignment_id}/sheet/draft")
def assignment_draft(request: Request, assignment: MembersAssignment, session: SessionDep, user: Writer,
                     form: Posted):
    return _save_draft(request, session, user, assignment, form)


@router.post("/assignments/{assignment_id}/sheet/import", response_class=HTMLResponse)
def assignment_import(request: Request, assignment: MembersAssignment, session: SessionDep, user: Writer,
                            file: UploadFile = File(...)):
    return _import(request, session, user, assignment, file)


@router.get("/sheet", response_class=HTMLResponse)
def free_sheet(request: Request, session: SessionDep, user: Writer):
    return _render(request, session, user, None, _draft_sheet(session, user, None))


@router.post("/sheet", response_class=HTMLResponse)
def free_sheet_action(request: Request, session: SessionDep, user: Writer, form: Posted):
    return _act(request, session, user, None, form)


@router.post("/sheet/draft")
def free_draft(request: Request, session: SessionDep, user: Writer, form: Posted):
    return _save_draft(request, session, user, None, form)


@router.post("/sheet/import", response_class=HTMLResponse)
def free_import(request: Request, session: SessionDep, user: Writer, file: UploadFile = File(...)):
    return _import(request, session, user, None, file)
