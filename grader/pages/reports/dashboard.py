"""The class dashboard's pages: the dashboard itself, its charts (SVG drawn here with matplotlib from the same data
as the page and GET /v1/courses/COURSE/dashboard), and the resend form of a failed or stuck case run.

For the course's instructors and auditors only (resending: instructors); anyone else gets the 404 page. The
charts are drawn on request from grader.services.reports.dashboard's data and cached by that data's content, so a page load draws
nothing new unless a grade or a measurement changed; the ETag lets the browser keep its copy.
"""

from __future__ import annotations

import hashlib
import threading
import warnings
from functools import lru_cache

from fastapi import APIRouter, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from grader import dispatch, i18n
from grader.i18n import N_
from grader.web.deps import SessionDep
from grader.web.errors import status_of
from grader.core.models import Course
from grader.pages.auth import SignedIn, SignedInFetch, StaffCourse, staff_course
from grader.pages.errors import not_found
from grader.pages.templates import TEMPLATES, request_locale
from grader.services.reports.dashboard import (
    BackendSpread,
    PredictionPlot,
    backend_spread,
    course_dashboard,
    graded_reports,
    predictions,
    case_run_of,
    resend_case_run,
)
from grader.services.rubrics import tolerance_review
from grader.services.errors import Conflict, Forbidden, NotFound

router = APIRouter(include_in_schema=False)


def _page(request: Request, session, user, row: Course, *, message: str | None = None, error: str | None = None,
          status_code: int = 200) -> HTMLResponse:
    return TEMPLATES.TemplateResponse(request, "reports/dashboard.html",
                                      {"user": user, "d": course_dashboard(session=session, course=row),
                                       "pending_signoffs": tolerance_review.pending_signoffs(session=session,
                                                                                              course=row),
                                       "message": message, "error": error}, status_code=status_code)


@router.get("/courses/{course}/dashboard", response_class=HTMLResponse)
def dashboard_page(request: Request, row: StaffCourse, session: SessionDep, user: SignedIn, resent: int | None = None):
    message = None
    run = case_run_of(session, course=row, case_run_id=resent) if resent else None
    if run is not None:  # say what is true now, not what the URL claims
        locale = request_locale(request)
        message = i18n.gettext(locale, "Case run %(id)s (%(name)s of submission %(submission)s) was re-sent: now "
                                       "%(state)s, delivery %(delivery)s on the %(queue)s queue.") % {
            "id": run.id, "name": run.name, "submission": run.submission_id, "state": i18n.gettext(locale, run.status),
            "delivery": run.delivery, "queue": run.backend}
    return _page(request, session, user, row, message=message)


@router.post("/courses/{course}/dashboard/case-runs/{case_run_id}/resend", response_class=HTMLResponse)
def resend_form(request: Request, row: StaffCourse, case_run_id: int, session: SessionDep, user: SignedIn):
    """The problems table's button. The session cookie is SameSite=Strict, so another site cannot post this.
    An auditor's or another course's press is refused by the service (grader.services.reports.dashboard.resend_case_run)."""
    try:
        resend_case_run(session=session, case_run_id=case_run_id, user=user, sender=dispatch)
    except (Conflict, Forbidden) as refused:  # shown on the dashboard beside the button, as the form's answer
        session.rollback()
        return _page(request, session, user, row, error=refused.detail, status_code=status_of(refused))
    return RedirectResponse(f"/courses/{row.name}/dashboard?resent={case_run_id}#problems",
                            status_code=status.HTTP_303_SEE_OTHER)


@router.get("/courses/{course}/dashboard/charts/{name}.svg")
def chart(request: Request, course: str, name: str, session: SessionDep, user: SignedInFetch):
    try:
        row = staff_course(course, session, user)
    except NotFound:
        row = None
    item = name.removeprefix("predictions-")
    if row is None or not (name == "backends" or (name.startswith("predictions-") and item in ("H1", "H4"))):
        return not_found(request, user, f"chart {name}")
    if name == "backends":
        data = backend_spread(session, row).model_dump_json()
    else:
        data = next(p for p in predictions(row, graded_reports(session, row)) if p.item == item).model_dump_json()
    locale = request_locale(request)  # the chart's words are the page's: one drawing per language
    etag = '"' + hashlib.sha256(f"{name}\n{locale}\n{data}".encode()).hexdigest()[:32] + '"'
    headers = {"ETag": etag, "Cache-Control": "private, no-cache"}
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=status.HTTP_304_NOT_MODIFIED, headers=headers)
    return Response(_svg(name, data, locale), media_type="image/svg+xml", headers=headers)


# --- drawing --------------------------------------------------------------------------------------------------------

CJK_FAMILIES = ("WenQuanYi Micro Hei", "Noto Sans CJK SC", "Noto Sans SC", "Source Han Sans SC")


@lru_cache(maxsize=1)
def _cjk_families() -> tuple[str, ...]:
    """The CJK_FAMILIES this host has (matplotlib logs every family it is asked for and cannot find)."""
    from matplotlib import font_manager

    have = {f.name for f in font_manager.fontManager.ttflist}
    return tuple(name for name in CJK_FAMILIES if name in have)

_DRAWING = threading.Lock()  # matplotlib's state is not thread-safe; the API serves requests on a thread pool
# One marker and one colour per (run, lane): the shape carries the meaning, the colour only repeats it.
SERIES = {("baseline", "low"): ("o", "#c2571a"), ("baseline", "high"): ("s", "#2b5fa8"),
          ("modified", "low"): ("^", "#c2571a"), ("modified", "high"): ("D", "#2b5fa8")}
BACKEND_STYLE = {"cpu": ("o", "#444444"), "rocm": ("s", "#b8322a"), "cuda": ("D", "#3a7d2c")}
# Words the data carries in English and the page and its charts show in the reader's language (the template's _()
# and _Words below): the items' quantities (grader.services.reports.dashboard.PREDICTED_ITEMS), runs and lanes.
WORDS = (N_("effective pair friction"), N_("sustained stop distance"), N_("baseline"), N_("modified"), N_("low"),
         N_("high"))


class _Words:
    """gettext in one locale, with %-style values: what a chart's labels are written with."""

    def __init__(self, locale: str):
        self.locale = locale

    def __call__(self, text: str, **values) -> str:
        translated = i18n.gettext(self.locale, text)
        return translated % values if values else translated


@lru_cache(maxsize=64)
def _svg(name: str, data: str, locale: str = i18n.DEFAULT) -> bytes:
    import io

    # lazy: matplotlib costs the API's start ~0.5 s and only a chart request draws
    import matplotlib
    from matplotlib.figure import Figure

    # The SVG keeps its text as text (svg.fonttype none): the browser draws it with the page's fonts, Chinese too.
    # matplotlib only measures it, with a CJK family after DejaVu where the host has one; elsewhere it measures CJK
    # glyphs it lacks as boxes, so its "missing glyph" warning says nothing about what the reader sees.
    with _DRAWING, warnings.catch_warnings(), matplotlib.rc_context({
            "svg.fonttype": "none", "font.size": 9, "svg.hashsalt": "dashboard",
            "font.family": ["DejaVu Sans", *_cjk_families()]}):
        warnings.filterwarnings("ignore", message=r"Glyph \d+ .* missing from font", category=UserWarning)
        if name == "backends":
            fig = _draw_backends(Figure(figsize=(10.0, 3.4)), BackendSpread.model_validate_json(data), _Words(locale))
        else:
            fig = _draw_predictions(Figure(figsize=(6.6, 4.2)), PredictionPlot.model_validate_json(data),
                                    _Words(locale))
        out = io.StringIO()
        fig.savefig(out, format="svg", bbox_inches="tight", metadata={"Date": None})
    return out.getvalue().encode()


def _draw_predictions(fig, plot, _=_Words(i18n.DEFAULT)):
    ax = fig.add_subplot()
    points = [r for r in plot.rows if r.predicted is not None and r.measured is not None]
    unit = f" ({plot.unit})" if plot.unit else ""
    quantity = _(plot.quantity)
    ax.set_xlabel(_("measured %(quantity)s%(unit)s", quantity=quantity, unit=unit))
    ax.set_ylabel(_("predicted %(quantity)s%(unit)s", quantity=quantity, unit=unit))
    ax.set_title(_("%(item)s: predicted against measured", item=plot.item), loc="left")
    if not points:
        ax.text(0.5, 0.5, _("no numeric prediction with a measurement yet"), ha="center", va="center",
                transform=ax.transAxes)
        return fig
    values = [v for r in points for v in (r.predicted, r.measured)]
    tol = max(plot.tolerances)
    low, high = min(values) - 2 * tol, max(values) + 2 * tol
    span = high - low
    low, high = low - 0.05 * span, high + 0.05 * span
    diagonal = [low, high]
    for t in plot.tolerances:  # the reviewed band: |predicted - measured| <= tolerance
        ax.fill_between(diagonal, [low - t, high - t], [low + t, high + t], color="#9bb7d4", alpha=0.35, lw=0,
                        label=_("within ±%(tolerance)s (reviewed tolerance)",
                                tolerance=f"{t:g}{' ' + plot.unit if plot.unit else ''}"))
    ax.plot(diagonal, diagonal, color="#555555", lw=0.8, ls="--", label=_("predicted = measured"))
    for (run, lane), (marker, colour) in SERIES.items():
        series = [r for r in points if (r.run, r.lane) == (run, lane)]
        if not series:
            continue
        inside = [r for r in series if r.within_tolerance]
        outside = [r for r in series if not r.within_tolerance]
        if inside:
            ax.scatter([r.measured for r in inside], [r.predicted for r in inside], marker=marker, color=colour,
                       s=36, label=_("%(run)s, %(lane)s", run=_(run), lane=_(lane)), zorder=3)
        if outside:  # hollow: outside the band (the table's "within tolerance" column says the same)
            ax.scatter([r.measured for r in outside], [r.predicted for r in outside], marker=marker, s=44,
                       facecolors="none", edgecolors=colour, linewidths=1.4,
                       label=_("%(run)s, %(lane)s, outside tolerance", run=_(run), lane=_(lane)), zorder=3)
    ax.set_xlim(low, high)
    ax.set_ylim(low, high)
    ax.set_aspect("equal")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    left_out = len(plot.rows) - len(points)
    if left_out:
        ax.text(0.99, 0.01, _("%(count)s not plotted (not stopped or not measured): see the table", count=left_out),
                ha="right",
                va="bottom", transform=ax.transAxes, fontsize=7, color="#555555")
    return fig


def _short(case: str) -> str:
    """A case name that fits under a tick: the lesson's friction cases lose their common prefix, long names wrap."""
    name = case.removeprefix("friction-").replace("sheet.", "sheet.\n").replace("-colors-swapped", "\ncolors-swapped")
    return name


def _draw_backends(fig, spread, _=_Words(i18n.DEFAULT)):
    panels = (("penetration_proxy", _("penetration proxy per contact case (mm)"), 1000.0),
              ("stop_distance", _("stop distance per friction lane (m)"), 1.0))
    backends = sorted({g.backend for g in spread.groups})
    axes = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.6]})
    for ax, (metric, title, scale) in zip(axes, panels):
        groups = [g for g in spread.groups if g.metric == metric]
        labels = list(dict.fromkeys(g.case + (f"\n{g.lane}" if g.lane else "") for g in groups))
        ax.set_title(title, loc="left")
        ax.grid(True, axis="y", lw=0.3)
        if not groups:
            ax.text(0.5, 0.5, _("no measurement yet"), ha="center", va="center", transform=ax.transAxes)
            ax.set_xticks([])
            continue
        width = 0.7 / max(len(backends), 1)
        for g in groups:
            x = labels.index(g.case + (f"\n{g.lane}" if g.lane else ""))
            x += (backends.index(g.backend) - (len(backends) - 1) / 2) * width
            marker, colour = BACKEND_STYLE.get(g.backend, ("x", "#777777"))
            ys = [v * scale for v in g.values]
            offsets = [x + width * 0.25 * ((i % 5) - 2) / 2 for i in range(len(ys))]  # small spread, no overlap
            ax.scatter(offsets, ys, marker=marker, color=colour, s=16, alpha=0.8, zorder=3)
            if g.median is not None:
                ax.hlines(g.median * scale, x - width * 0.4, x + width * 0.4, color=colour, lw=1.5)
        ticks = []
        for label in labels:  # runs without a sustained stop have no distance to plot: the tick label counts them
            missing = [f"{g.backend} {g.not_stopped}" for g in groups
                       if g.case + (f"\n{g.lane}" if g.lane else "") == label and g.not_stopped]
            ticks.append(_short(label) + ("\n" + _("not stopped: %(runs)s", runs=", ".join(missing)) if missing else ""))
        ax.set_xticks(range(len(labels)), ticks, fontsize=7)
        ax.set_xlim(-0.6, len(labels) - 0.4)
        ax.margins(y=0.12)
    for backend in backends:
        marker, colour = BACKEND_STYLE.get(backend, ("x", "#777777"))
        axes[1].scatter([], [], marker=marker, color=colour, label=backend)
    if backends:
        axes[1].legend(title=_("actual backend") + "\n" + _("(bar: median)"), fontsize=7, title_fontsize=7, frameon=False,
                       loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes: never over a marker
    fig.tight_layout()
    return fig
