"""The report's figures drawn in a real browser (Debian's chromium driven by Playwright) from the series the app
serves, over the real stack (API over HTTP, a Celery worker on Redis, PostgreSQL, real Genesis runs): every chart is
drawn with its runs' colours, zooms by dragging and from the keyboard, reads values on hover, breaks no rule of the
pages' CSP, and the report is complete (lab check shown) with no figure file written by the service."""

from __future__ import annotations

from pathlib import Path

import httpx
import pytest

from tests.integration.helpers import events, signed_in, wait_until

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SHOTS = Path("/tmp/shots/figures")
# report_charts.js CASE_COLORS: the contact cases' lines, in the order of the series
CASE_COLORS = [(0x00, 0x72, 0xB2), (0xD5, 0x5E, 0x00), (0x00, 0x9E, 0x73), (0xCC, 0x79, 0xA7), (0xE6, 0x9F, 0x00),
               (0x56, 0xB4, 0xE9)]


def _open(browser, stack, who: str, submission: int, *, width: int = 1280):
    """The report signed in as `who`, with every console error and failed page script collected."""
    SHOTS.mkdir(parents=True, exist_ok=True)
    page = signed_in(browser, stack, who, width=width)
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(f"{stack.url}/submissions/{submission}")
    charts = page.locator("#figures .chart[data-src]")
    wait_until(lambda: all(charts.evaluate_all("els => els.map(e => e.hasAttribute('data-series'))")),
               "every chart drawn or failed", limit_s=60)
    return page, errors


def _pixels(page, chart_id: str, rgb: tuple[int, int, int]) -> int:
    """Canvas pixels of chart `chart_id` within a small distance of colour `rgb`: the data drawn, not the axes."""
    return page.locator(f"[id='{chart_id}'] canvas").evaluate(
        """(c, rgb) => { const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let n = 0;
           for (let i = 0; i < d.length; i += 4) {
             if (d[i + 3] > 200 && Math.abs(d[i] - rgb[0]) + Math.abs(d[i + 1] - rgb[1]) + Math.abs(d[i + 2] - rgb[2]) < 60) n++;
           } return n; }""", list(rgb))


def _x_range(page, chart_id: str) -> tuple[float, float]:
    el = page.locator(f"[id='{chart_id}']")
    return float(el.get_attribute("data-x-min")), float(el.get_attribute("data-x-max"))


def test_the_report_draws_its_charts_from_the_stored_series_and_they_zoom(browser, stack, graded):
    submission = graded["alice"]["id"]
    series = httpx.get(f"{stack.url}/submissions/{submission}/series.json",
                       headers={"Authorization": f"Bearer {stack.tokens['alice']}"}, timeout=60).json()
    contact = [r for r in series["runs"] if r["kind"] == "contact" and r.get("series")]
    friction = [r for r in series["runs"] if r["kind"] == "friction" and r.get("lanes")]
    page, errors = _open(browser, stack, "alice", submission)

    # The report is complete: the lab check is on it, and the service drew no PNG for it (none on the worker's disk).
    line = page.locator("#check-line").inner_text()
    assert line.startswith("L03 CHECK: PASSED"), (line, [(e.state, e.detail) for e in events(stack, submission)])
    assert not list((stack.data_dir / "artifacts" / "submissions" / str(submission)).rglob("*.png"))
    assert not (stack.data_dir / "artifacts" / "figure-cache").exists()
    assert page.locator("#figures img").count() == 0

    charts = page.locator("#figures .chart[data-src]")
    assert charts.count() == 4 + 3 * len(friction)
    drawn = dict(zip(charts.evaluate_all("els => els.map(e => e.id)"),
                     map(int, charts.evaluate_all("els => els.map(e => e.getAttribute('data-series'))"))))
    assert drawn["chart-contact-z"] == len(contact) + 1  # every contact case and the ideal rest height
    assert all(n > 0 for n in drawn.values()), drawn
    assert page.locator("#figures .chart-failed").count() == 0
    # Non-blank: the contact cases' lines are on the canvas in their colours (N1 and N4 coincide: the later one
    # covers the earlier), and each lane of a run in its own.
    per_case = [_pixels(page, "chart-contact-z", rgb) for rgb in CASE_COLORS[:len(contact)]]
    assert sum(per_case) > 300 and per_case[-1] > 50, per_case
    base = next(r for r in friction if r["name"] == "friction-baseline")
    for lane in base["lanes"]:
        rgb = tuple(int(lane["color"][i:i + 2], 16) for i in (1, 3, 5))
        assert _pixels(page, "chart-friction-x-friction-baseline", rgb) > 100, lane["name"]

    # Zoom by dragging across the chart: the x-range narrows to the dragged window; a double-click restores it.
    whole = _x_range(page, "chart-contact-z")
    page.locator("[id='chart-contact-z']").scroll_into_view_if_needed()  # the mouse acts on the viewport
    over = page.locator("[id='chart-contact-z'] .u-over").bounding_box()
    y = over["y"] + over["height"] / 2
    page.mouse.move(over["x"] + 0.3 * over["width"], y)
    page.mouse.down()
    page.mouse.move(over["x"] + 0.45 * over["width"], y, steps=8)
    page.mouse.up()
    lo, hi = _x_range(page, "chart-contact-z")
    assert whole[0] < lo < hi < whole[1] and (hi - lo) < 0.3 * (whole[1] - whole[0]), (whole, lo, hi)
    page.mouse.dblclick(over["x"] + over["width"] / 2, y)
    assert _x_range(page, "chart-contact-z") == pytest.approx(whole)

    # From the keyboard: the contact-window button zooms every contact chart around the first contact.
    first = min(r["metrics"]["first_contact_time"] for r in contact)
    page.focus("button[data-zoom=contact]")
    page.keyboard.press("Enter")
    for chart in ("chart-contact-vz", "chart-contact-clearance"):
        assert _x_range(page, chart) == pytest.approx((first - 0.05, first + 0.30)), chart
    page.locator("#figures").scroll_into_view_if_needed()
    page.screenshot(path=str(SHOTS / "report_charts_contact_window.png"), full_page=False)
    page.focus("button[data-zoom=whole]")
    page.keyboard.press("Enter")
    assert _x_range(page, "chart-contact-vz") == pytest.approx(whole)

    # Hovering reads every series at one sample in the legend.
    page.locator("[id='chart-contact-z']").scroll_into_view_if_needed()
    over = page.locator("[id='chart-contact-z'] .u-over").bounding_box()
    y = over["y"] + over["height"] / 2
    page.mouse.move(over["x"] + 0.5 * over["width"], y)
    values = page.locator("[id='chart-contact-z'] .u-legend .u-series .u-value").all_inner_texts()
    assert values[0] not in ("", "--", "\u2013") and float(values[0]) > 0, values

    # Each chart has its text alternative: a caption with the key numbers and links to the data.
    caption = page.locator("[id='caption-friction-x-friction-baseline']").inner_text()
    assert "stopped after" in caption or "not stopped" in caption
    assert page.locator("[id='chart-contact-z']").get_attribute("aria-describedby") == "caption-contact-z"
    assert errors == [], errors  # no script error, no CSP violation (chromium reports each as a console error)
    page.screenshot(path=str(SHOTS / "report_charts_desktop.png"), full_page=True)
    for chart in ("friction-x-friction-baseline", "friction-vx-sheet.table_exercise", "contact-clearance"):
        page.locator(f"[id='figure-{chart}']").screenshot(path=str(SHOTS / f"report_chart_{chart}.png"))


def test_the_charts_fit_a_phone(browser, stack, graded):
    submission = graded["alice"]["id"]
    page, errors = _open(browser, stack, "alice", submission, width=390)
    # Nothing of the figures reaches past the screen's edge (what another section does is its own test's).
    wide = page.locator("#figures").evaluate("""f => [f, ...f.querySelectorAll('*')]
        .filter(e => e.getBoundingClientRect().right > 391)
        .map(e => e.tagName + '#' + e.id + '.' + e.className + ' ' + Math.round(e.getBoundingClientRect().right))""")
    assert wide == [], wide
    widths = page.locator("#figures .chart canvas").evaluate_all("els => els.map(c => c.getBoundingClientRect().width)")
    assert widths and all(0 < w <= 390 for w in widths), widths
    assert sum(_pixels(page, "chart-contact-z", rgb) for rgb in CASE_COLORS) > 150
    assert errors == [], errors
    page.locator("#figure-contact-z").scroll_into_view_if_needed()
    page.screenshot(path=str(SHOTS / "report_charts_phone.png"), full_page=False)
    page.locator("[id='figure-friction-x-friction-baseline']").screenshot(path=str(SHOTS / "report_chart_phone_friction.png"))


def test_another_student_gets_no_series(stack, graded):
    bob = {"Authorization": f"Bearer {stack.tokens['bob']}"}
    answer = httpx.get(f"{stack.url}/submissions/{graded['alice']['id']}/series.json", headers=bob, timeout=60)
    assert answer.status_code == 404 and "friction-baseline" not in answer.text
