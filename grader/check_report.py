"""Human-readable lab check reports, of any lesson (contact and friction tables where such runs are there): one
self-contained HTML file and a plain-text summary for the command line.

Inputs are plain: a verdict, duck-typed conditions (anything with .title, .passed, .evidence and optionally .id),
CaseResults and figure paths. Every piece of text that reaches HTML goes through html.escape, because case names,
errors and captured output come from students.
"""

from __future__ import annotations

import base64
import html
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from rubric import CaseResult, ContactCase, FrictionCase
from rubric.check import verdict_line

NOT_STOPPED = "not stopped within the measured window"
REPORT_NAME = "report.html"

# ------------------------------------------------------------------------------------------- rows (shared data)


def _verdict(verdict: bool, conditions: Iterable = (), line=None) -> str:
    """The verdict line of the lesson whose check this is (`line`, a Lesson's verdict_line; by default rubric.check's)."""
    return (line or verdict_line)(verdict, [str(c.title) for c in conditions if not c.passed])


def _num(value: float | None, fmt: str, scale: float = 1.0) -> str:
    return "n/a" if value is None else format(value * scale, fmt)


def contact_rows(results: Mapping[str, CaseResult]) -> list[dict[str, str]]:
    """One formatted row per contact case; a failed case keeps its row with its status instead of numbers."""
    rows = []
    for r in results.values():
        if not isinstance(r.spec, ContactCase):
            continue
        s = r.spec
        row = {"case": s.name, "dt (s)": f"{s.dt:g}", "substeps": str(s.substeps), "substep_dt (s)": f"{s.substep_dt:.4g}",
               "samples": str(s.sample_count), "internal updates": str(s.internal_updates)}
        if not (r.ok and r.arrays):
            rows.append(row | {"status": r.status})
            continue
        m = r.metrics
        rows.append(row | {
            "samples": str(m.n_samples),
            "penetration proxy (mm)": _num(m.penetration_proxy, ".2f", 1e3),
            "first contact (s)": _num(m.first_contact_time, ".2f"),
            "contact samples": str(m.contact_samples),
            "separation samples / duration": f"{m.separation_samples} / {m.separation_duration:.2f} s",
            "max upward vz after contact (m/s)": _num(m.max_upward_velocity_after_contact, ".3f"),
            f"tail settling error, last {m.tail_window:g} s (mm)": _num(m.tail_settling_error, "+.3f", 1e3),
            "max tilt (\u00b0)": _num(m.max_tilt_deg, ".2f"),
            "status": r.status,
        })
    return rows


def lane_rows(results: Mapping[str, CaseResult]) -> list[dict[str, str]]:
    """One formatted row per friction lane per run; a stop that was not observed is said so, never invented."""
    rows = []
    for r in results.values():
        if not isinstance(r.spec, FrictionCase):
            continue
        if not (r.ok and r.arrays):
            rows.append({"run": r.spec.name, "lane": "\u2014", "status": r.status})
            continue
        for lane in r.spec.lanes:
            m = r.metrics.lane(lane.name)
            rows.append({
                "run": r.spec.name,
                "lane": lane.name,
                "table \u03bc": f"{m.table_friction:.2f}",
                "cube \u03bc": f"{m.cube_friction:.2f}",
                "effective pair \u03bc (engine)": _num(m.pair_friction, ".2f")
                + ("" if m.pair_friction_agrees else f" \u2260 rule {m.pair_friction_rule:.2f}"),
                "stop time (s)": _num(m.stop.time, ".2f") if m.stop.stopped else NOT_STOPPED,
                "stop distance (m)": _num(m.stop.distance, ".3f") if m.stop.stopped else NOT_STOPPED,
                "final displacement (m)": f"{m.final_displacement:.3f}",
                "max |\u03c9| (rad/s)": f"{m.max_abs_omega:.2f}",
                "status": r.status,
            })
    return rows


def lane_color(results: Mapping[str, CaseResult], run: str, lane: str) -> str | None:
    """The lane's Surface colour as a CSS rgb() value, so the table matches the figures' legend."""
    r = results.get(run)
    spec_lane = next((item for item in getattr(r.spec, "lanes", ()) if item.name == lane), None) if r else None
    if spec_lane is None:
        return None
    red, green, blue = (round(255 * c) for c in spec_lane.color)
    return f"rgb({red}, {green}, {blue})"


def provenance_rows(results: Mapping[str, CaseResult]) -> list[dict[str, str]]:
    """Where each case's numbers came from: backend asked for and used, device, versions, mode, timings, rendering."""
    rows = []
    for r in results.values():
        p = r.provenance
        row = {"case": r.spec.name, "status": r.status, "requested backend": r.spec.backend}
        if p is None:
            rows.append(row | {"actual backend": "n/a (no provenance)", "error": r.error or ""})
            continue
        t = p.timings
        rows.append(row | {
            "requested backend": p.requested_backend,
            "actual backend": p.actual_backend,
            "device": f"{p.torch_device} ({p.device_name})",
            "versions": ", ".join(f"{k} {v}" for k, v in sorted(p.versions.items())),
            "precision / seed": f"{p.precision} / {p.seed}",
            "execution mode": f"{p.execution_mode}, {p.scene} scene",
            "timings (s)": (f"import {t.import_s:.1f}, init {t.init_s:.1f}, build {t.build_s:.1f}, "
                            f"steps {t.steps_s:.2f}, render {t.render_s:.2f}; wall {r.wall_s:.1f}"),
            "rendering": f"{p.rendering.status} ({p.rendering.frames} frames): {p.rendering.detail}",
            "error": r.error or "",
        })
    return rows


# ------------------------------------------------------------------------------------------------------ plain text


# ------------------------------------------------------------------------------------------------------------ HTML

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 2rem auto; max-width: 1500px;
       color: #1b1b1b; padding: 0 1rem; line-height: 1.4; }
h1 { font-size: 1.5rem; margin-bottom: .2rem; }
h2 { font-size: 1.15rem; margin-top: 2rem; border-bottom: 1px solid #ddd; padding-bottom: .2rem; }
.verdict { font-size: 1.35rem; font-weight: 700; padding: .7rem 1rem; border-radius: 6px; margin: 1rem 0; }
.verdict.pass { background: #e3f4e3; color: #145214; border: 1px solid #8cc98c; }
.verdict.fail { background: #fbe4e4; color: #7a1010; border: 1px solid #e09a9a; }
table { border-collapse: collapse; font-size: .85rem; margin: .5rem 0; }
th, td { border: 1px solid #d6d6d6; padding: .3rem .5rem; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.ok { color: #145214; font-weight: 600; } .bad { color: #7a1010; font-weight: 600; }
.swatch { display: inline-block; width: .9em; height: .9em; border: 1px solid #444; margin-right: .35em;
          vertical-align: -.1em; }
figure { margin: 1.2rem 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: .85rem; color: #555; }
.meta { color: #555; font-size: .85rem; }
pre { white-space: pre-wrap; font-size: .8rem; background: #f7f7f7; padding: .5rem; }
"""


def _e(value) -> str:
    return html.escape(str(value), quote=True)


def _is_number(text: str) -> bool:
    try:
        float(text.split(" ")[0])
        return True
    except ValueError:
        return False


def _html_table(rows: list[dict[str, str]], *, cell_prefix=None) -> str:
    if not rows:
        return "<p class='meta'>none</p>"
    columns = list(dict.fromkeys(key for row in rows for key in row))
    head = "".join(f"<th>{_e(c)}</th>" for c in columns)
    body = []
    for row in rows:
        cells = []
        for c in columns:
            value = row.get(c, "")
            prefix = cell_prefix(row, c) if cell_prefix else ""
            cls = " class='num'" if _is_number(value) else ""
            cells.append(f"<td{cls}>{prefix}{_e(value)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def _conditions_table(conditions: list) -> str:
    rows = []
    for c in conditions:
        mark = "<span class='ok'>passed</span>" if c.passed else "<span class='bad'>FAILED</span>"
        cid = getattr(c, "id", None)
        rows.append(f"<tr><td>{_e(cid) if cid is not None else ''}</td><td>{_e(c.title)}</td><td>{mark}</td>"
                    f"<td>{_e(c.evidence or '')}</td></tr>")
    head = "<tr><th>id</th><th>condition</th><th>result</th><th>measured evidence</th></tr>"
    return f"<table><thead>{head}</thead><tbody>{''.join(rows)}</tbody></table>"


def _figure_html(path: Path, out_dir: Path, *, embed: bool) -> str:
    if not path.is_file():
        # A report is still written when a figure failed; the gap is stated, not hidden.
        return f"<p class='bad'>figure missing: {_e(path.name)}</p>"
    if embed:
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        src = f"data:image/png;base64,{data}"
    else:
        # A relative link keeps the report and its figures movable together as one folder.
        src = Path(os.path.relpath(path, out_dir)).as_posix()
    return (f"<figure><img src=\"{_e(src)}\" alt=\"{_e(path.stem)}\">"
            f"<figcaption>{_e(path.name)}</figcaption></figure>")


def _header(verdict: bool, conditions: list, results: Mapping[str, CaseResult], title: str, line=None) -> str:
    cls = "pass" if verdict else "fail"
    backends = sorted({r.backend for r in results.values()})
    versions = sorted({r.provenance.versions.get("genesis", "?") for r in results.values() if r.provenance})
    meta = (f"cases: {', '.join(results)} | actual backend: {', '.join(backends) or 'n/a'} | "
            f"genesis {', '.join(versions) or 'version unknown'}")
    return (f"<h1>{_e(title)}</h1><p class='meta'>{_e(meta)}</p>"
            f"<div class='verdict {cls}'>{_e(_verdict(verdict, conditions, line))}</div>")


def _errors_html(results: Mapping[str, CaseResult]) -> str:
    failed = [r for r in results.values() if not r.ok]
    if not failed:
        return ""
    parts = ["<h2>Failed cases</h2>"]
    for r in failed:
        tail = (r.stderr or "")[-4000:]
        parts.append(f"<h3>{_e(r.spec.name)}: {_e(r.status)}</h3><pre>{_e(r.error or '')}\n\n{_e(tail)}</pre>")
    return "".join(parts)


def render_check_html(*, verdict: bool, conditions: Iterable, results: Mapping[str, CaseResult],
                      figures: Iterable[str | Path] = (), out_dir: str | Path = ".", embed: bool = True,
                      title: str = "L03 \u00b7 Rigid-Body Physics and Stable Simulation: lab check",
                      line=None) -> str:
    """The report as an HTML string (see write_check_report). `line`: the lesson's verdict_line (the default
    lesson's when not given); the contact and friction tables appear where the results hold such runs (or none at
    all: a check that ran nothing still shows what it lacks)."""
    conditions, out_dir = list(conditions), Path(out_dir)
    contact, sliding = contact_rows(results), lane_rows(results)
    part_tables = bool(contact or sliding or not results)

    def swatch(row, column):
        color = lane_color(results, row.get("run", ""), row.get("lane", "")) if column == "lane" else None
        return f"<span class='swatch' style='background: {_e(color)}'></span>" if color else ""

    body = [
        _header(verdict, conditions, results, title, line),
        "<h2>Conditions</h2>", _conditions_table(conditions),
        *([] if not part_tables else [
        "<h2>Part A: contact cases</h2>",
        "<p class='meta'>penetration proxy = max(0, ideal rest height \u2212 lowest sampled centre height), sampled "
        "once per outer dt: not the solver's continuous penetration depth. Separation samples need contact count 0 "
        "and clearance above the declared tolerance after first contact; their duration is quantized by dt.</p>",
        _html_table(contact),
        "<h2>Part B: friction lanes</h2>",
        "<p class='meta'>effective pair \u03bc: the sliding friction the engine assigned to each lane's cube-table "
        "contacts, read from its contact data and cross-checked against the Genesis 1.3.3 rule max(table \u03bc, cube "
        "\u03bc) (a disagreement is shown as \u2260 rule). A stop is the "
        "first sample of a full hold interval with |vx| below the declared stop speed.</p>",
        _html_table(sliding, cell_prefix=swatch)]),
        "<h2>Provenance</h2>", _html_table(provenance_rows(results)),
        _errors_html(results),
        "<h2>Figures</h2>",
        *(_figure_html(Path(p), out_dir, embed=embed) for p in figures),
    ]
    return ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<title>{_e(_verdict(verdict, conditions, line))}</title><style>{CSS}</style></head><body>"
            + "\n".join(body) + "</body></html>\n")


def write_check_report(out_dir: str | Path, *, verdict: bool, conditions: Iterable, results: Mapping[str, CaseResult],
                       figures: Iterable[str | Path] = (), embed: bool = True, filename: str = REPORT_NAME,
                       lesson=None) -> Path:
    """Write a lesson's check report into out_dir and return its path (`lesson`: its declaration, for its title and
    verdict line; the default lesson's when not given); figures embedded as base64 unless embed=False."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / filename
    named = {} if lesson is None else {"title": f"{lesson.title('en')}: lab check", "line": lesson.verdict_line}
    path.write_text(render_check_html(verdict=verdict, conditions=conditions, results=results, figures=figures,
                                      out_dir=out_dir, embed=embed, **named), encoding="utf-8")
    return path


__all__ = [
    "NOT_STOPPED",
    "contact_rows",
    "lane_rows",
    "provenance_rows",
    "render_check_html",
    "write_check_report",
]
