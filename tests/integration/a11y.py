"""axe-core (bundled by axe-playwright-python; nothing from a CDN) run on a page a Playwright browser shows: a test
fails on every serious or critical violation, each listed with its rule, the elements and what to fix."""

from __future__ import annotations

from axe_playwright_python.sync_playwright import Axe

BLOCKING = ("serious", "critical")
# WCAG 2.1 A and AA, the rules a course's accessibility policy asks for, and axe's own best practices.
TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa", "best-practice"]
_AXE = Axe()


def violations(page) -> list[dict]:
    """Every axe violation on the page as it is now (axe is injected into the page by the debugging protocol, which
    the pages' CSP does not govern)."""
    results = _AXE.run(page, options={"runOnly": {"type": "tag", "values": TAGS}, "resultTypes": ["violations"]})
    return results.response["violations"]


def describe(found: list[dict], limit: int = 6) -> str:
    lines = []
    for v in found:
        lines.append(f"- {v['id']} ({v['impact']}): {v['help']} [{v['helpUrl']}]")
        for node in v["nodes"][:limit]:
            summary = " ".join((node.get("failureSummary") or "").split())
            lines.append(f"    {' '.join(map(str, node['target']))}: {summary[:300]}")
        if len(v["nodes"]) > limit:
            lines.append(f"    ... and {len(v['nodes']) - limit} more")
    return "\n".join(lines)


def assert_accessible(page, what: str) -> list[dict]:
    """Fail on any serious or critical violation on `what` (a page's name for the message); the minor and moderate
    ones are returned for the caller to report."""
    found = violations(page)
    blocking = [v for v in found if v["impact"] in BLOCKING]
    assert not blocking, f"axe-core: {len(blocking)} serious or critical violations on {what} ({page.url}):\n" \
                         + describe(blocking)
    return [v for v in found if v["impact"] not in BLOCKING]
