"""Whether a page fits its window, measured in the browser: no horizontal scroll, no table cell wider than itself, and
no word broken inside. A word is a run of ASCII characters but the hyphen in one text node (a <wbr> after a separator
ends a text node and a line may end after a hyphen, so "float32-level" or a long name may wrap there; Chinese wraps
between characters, as it should); it is broken when its rendered
pieces sit on more than one line. Also each cell's CSS: overflow-wrap anywhere or word-break break-all would let a
table shrink a column below its longest word (how "prox y_re solu tion" came about)."""

from __future__ import annotations

from pathlib import Path

from tests.integration.a11y import assert_accessible

MEASURE = """(selector) => {
  const doc = document.documentElement;
  const out = {scroll: doc.scrollWidth, client: doc.clientWidth, overflowing: [], broken: [], breaking: []};
  const name = (cell) => (cell.closest('tr') && cell.closest('tr').id ? cell.closest('tr').id + ': ' : '')
    + cell.textContent.trim().replace(/\\s+/g, ' ').slice(0, 50);
  for (const cell of document.querySelectorAll(selector)) {
    if (!cell.getClientRects().length) continue;  // not shown (a hidden row)
    const style = getComputedStyle(cell);
    if (style.overflowWrap === 'anywhere' || ['break-all', 'break-word'].includes(style.wordBreak))
      out.breaking.push(name(cell) + ` (${style.overflowWrap}, ${style.wordBreak})`);
    if (cell.scrollWidth > cell.clientWidth + 1) out.overflowing.push(name(cell));
    const walker = document.createTreeWalker(cell, NodeFilter.SHOW_TEXT);
    for (let node = walker.nextNode(); node; node = walker.nextNode()) {
      const words = /[\\x21-\\x2c\\x2e-\\x7e]+/g;  // a hyphen is a separator a line may end at
      let m;
      while ((m = words.exec(node.data))) {
        const range = document.createRange();
        range.setStart(node, m.index);
        range.setEnd(node, m.index + m[0].length);
        const lines = new Set([...range.getClientRects()].filter(r => r.width > 0).map(r => Math.round(r.bottom)));
        if (lines.size > 1) out.broken.push(m[0]);
      }
    }
  }
  // what sticks out, outermost first (for the message): an element whose right edge passes the window's, not
  // inside a table that scrolls by itself
  out.wide = [...document.querySelectorAll('body *')].filter(e => e.getBoundingClientRect().right > doc.clientWidth + 1
      && !(e.closest('table') && getComputedStyle(e.closest('table')).overflowX === 'auto' && e.closest('table') !== e))
    .slice(0, 6).map(e => `${e.tagName.toLowerCase()}${e.id ? '#' + e.id : ''}${e.className && typeof e.className === 'string' ? '.' + e.className.split(' ').join('.') : ''}`);
  return out;
}"""


def measure(page, selector: str = "main table th, main table td") -> dict:
    return page.evaluate(MEASURE, selector)


def assert_fits(page, what: str, selector: str = "main table th, main table td") -> dict:
    """The page at its window's width scrolls only down, and no table cell breaks a word or overflows."""
    found = measure(page, selector)
    assert found["scroll"] <= found["client"], \
        f"{what}: {found['scroll']} px wide in a {found['client']} px window; sticking out: {found['wide']}"
    assert not found["breaking"], f"{what}: cells whose CSS breaks words anywhere: {found['breaking'][:8]}"
    assert not found["broken"], f"{what}: words broken inside: {found['broken'][:12]}"
    assert not found["overflowing"], f"{what}: cells wider than themselves: {found['overflowing'][:8]}"
    return found


def pages_in_both_languages(browser, sign_in, url: str, shots: Path, name: str, *, ready: str = "main",
                            fits: bool = True) -> None:
    """The page `url` in English and Chinese, at desktop (1280 px) and phone (390 px) width: no horizontal scroll
    (on a phone a wide table scrolls inside itself), every table fitting without a word broken at desktop width
    (`fits`), axe clean, a full-page screenshot of each as
    shots/NAME-{en,zh}-{1280,390}.png. `sign_in(browser, locale=..., width=...)` gives a signed-in page."""
    for locale in ("en", "zh-CN"):
        for width in (1280, 390):
            page = sign_in(browser, locale=locale, width=width)
            page.goto(url)
            page.wait_for_selector(ready)
            tag = f"{name}-{locale[:2]}-{width}"
            if locale != "en":
                assert page.get_attribute("html", "lang") == "zh", tag
            if fits and width == 1280:
                assert_fits(page, tag)
            found = measure(page)  # on a phone a wide table scrolls inside itself; the page never does
            assert found["scroll"] <= found["client"], \
                f"{tag}: {found['scroll']} px in {found['client']} px; sticking out: {found['wide']}"
            assert_accessible(page, tag)
            page.screenshot(path=str(shots / f"{tag}.png"), full_page=True)
            page.close()
