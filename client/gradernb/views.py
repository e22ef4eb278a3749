"""What the client shows in Jupyter: tables, the check, a live progress bar, the report with its charts (inline SVG
drawn from the measured series); plain text outside a notebook."""

from __future__ import annotations

from html import escape
from typing import Any

STYLE = ("<style>.gradernb td,.gradernb th{text-align:left;vertical-align:top;padding:2px 8px}"
         ".gradernb .bad{color:#a00;font-weight:bold}.gradernb .ok{color:#070;font-weight:bold}</style>")


def text(value: Any) -> str:
    """A value as a reader reads it: floats to 4 significant digits (the evidence's arrays are kept whole by the
    service), a quantity with its unit."""
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, dict) and set(value) == {"value", "unit"}:
        return f"{text(value['value'])} {value['unit']}"
    return str(value)


def html_table(columns: list[str], rows: list[list[Any]], cls: str = "") -> str:
    head = "".join(f"<th>{escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{cell if isinstance(cell, Html) else escape(text(cell))}</td>"
                                    for cell in row) + "</tr>" for row in rows)
    return f'<table class="gradernb {cls}"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


class Html(str):
    """Markup already escaped: a table cell that is put in as it is."""


class Table:
    """Rows of dicts shown as a table (`_repr_html_` in Jupyter); indexable like the list it holds."""

    def __init__(self, columns: list[str], rows: list[dict], *, title: str = ""):
        self.columns, self.rows, self.title = columns, rows, title

    def __getitem__(self, index):
        return self.rows[index]

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self):
        return iter(self.rows)

    def _repr_html_(self) -> str:
        title = f"<h4>{escape(self.title)}</h4>" if self.title else ""
        return STYLE + title + html_table(self.columns, [[r.get(c) for c in self.columns] for r in self.rows])

    def __repr__(self) -> str:
        lines = [self.title] if self.title else []
        lines.append(" | ".join(self.columns))
        lines += [" | ".join(text(r.get(c)) for c in self.columns) for r in self.rows]
        return "\n".join(lines)


def show(obj) -> None:
    """Display `obj` in Jupyter (its HTML), or print it."""
    try:
        from IPython.display import display  # a kernel always has it; a plain interpreter prints
    except ImportError:
        print(repr(obj))
        return
    display(obj)


class Live:
    """One output area updated in place: a progress bar in Jupyter, lines printed elsewhere."""

    def __init__(self):
        try:
            from IPython.display import HTML, display

            self.handle, self.HTML = display(HTML(""), display_id=True), HTML
        except ImportError:
            self.handle = None
        self.last = ""

    def update(self, html: str, words: str) -> None:
        if self.handle is not None:
            self.handle.update(self.HTML(html))
        elif words != self.last:
            print(words)
        self.last = words


def progress_html(p: dict) -> tuple[str, str]:
    """The progress bar and its words from the service's progress (GET /v1/submissions/ID/progress)."""
    counts = p.get("counts") or {}
    runs = p.get("runs") or []
    done = sum(1 for r in runs if r.get("status") in ("done", "failed"))
    total = max(len(runs), 1)
    waiting = [r for r in runs if r.get("position")]
    parts = [f"{done} of {len(runs)} case runs done", f"submission {p.get('status')}"]
    if waiting:
        first = min(waiting, key=lambda r: r["position"])
        parts.append(f"next in queue: place {first['position']} ({first.get('backend')})")
    if p.get("own_s") is not None and not p.get("finished"):
        ahead = p.get("ahead_s") or 0
        parts.append(f"about {round((p['own_s'] or 0) + ahead)} s left")
    if p.get("warming_up"):
        parts.append("the worker is warming up")
    words = "; ".join(parts)
    html = (f'<div class="gradernb"><progress max="{total}" value="{done}" style="width:60%"></progress> '
            f'<span>{escape(words)}</span></div>')
    return html, words


def _svg_chart(title: str, series: list[tuple[str, list[float], list[float]]], unit: str) -> str:
    """A small line chart: each (name, t, y) a polyline, axes labelled with their ranges."""
    points = [(t, y) for _, ts, ys in series for t, y in zip(ts, ys) if t is not None and y is not None]
    if not points:
        return ""
    width, height, pad = 420, 180, 34
    t0, t1 = min(p[0] for p in points), max(p[0] for p in points)
    y0, y1 = min(p[1] for p in points), max(p[1] for p in points)
    t1, y1 = (t1 if t1 > t0 else t0 + 1), (y1 if y1 > y0 else y0 + 1)
    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"]
    lines = []
    for n, (name, ts, ys) in enumerate(series):
        xy = " ".join(f"{pad + (t - t0) / (t1 - t0) * (width - 2 * pad):.1f},"
                      f"{height - pad - (y - y0) / (y1 - y0) * (height - 2 * pad):.1f}"
                      for t, y in zip(ts, ys) if t is not None and y is not None)
        colour = colours[n % len(colours)]
        lines.append(f'<polyline fill="none" stroke="{colour}" stroke-width="1.5" points="{xy}"/>'
                     f'<text x="{width - pad}" y="{14 + 12 * n}" font-size="10" text-anchor="end" '
                     f'fill="{colour}">{escape(name)}</text>')
    axes = (f'<line x1="{pad}" y1="{height - pad}" x2="{width - pad}" y2="{height - pad}" stroke="#888"/>'
            f'<line x1="{pad}" y1="{pad}" x2="{pad}" y2="{height - pad}" stroke="#888"/>'
            f'<text x="{pad}" y="{height - 8}" font-size="10">t {t0:g}–{t1:g} s</text>'
            f'<text x="2" y="{pad - 6}" font-size="10">{escape(unit)} {y0:.3g}–{y1:.3g}</text>')
    return (f'<figure style="display:inline-block;margin:4px"><svg xmlns="http://www.w3.org/2000/svg" '
            f'width="{width}" height="{height}" role="img" aria-label="{escape(title)}">{axes}{"".join(lines)}</svg>'
            f'<figcaption style="font-size:11px">{escape(title)}</figcaption></figure>')


def charts_html(series: dict) -> str:
    """The report's trajectory charts from the measured series (GET /v1/submissions/ID/series): the contact cases'
    height over time, and each friction case's lanes' displacement."""
    runs = [r for r in series.get("runs", []) if r.get("series")]
    contact = [(r["name"], r["series"]["t"], r["series"]["z"]) for r in runs if "z" in r["series"]]
    out = [_svg_chart("contact cases: cube height z", contact, "z (m)")] if contact else []
    for r in runs:
        lanes = [(lane.get("name", "?"), r["series"]["t"], lane.get("x") or [])
                 for lane in r.get("lanes", [])]
        if any(ys for _, _, ys in lanes):
            out.append(_svg_chart(f"{r['name']}: lanes' position x", lanes, "x (m)"))
    withheld = series.get("withheld") or {}
    if withheld:
        out.append("<p>" + escape("Not shown yet: " + ", ".join(f"{k} ({v})" for k, v in withheld.items())) + "</p>")
    return "".join(out)
