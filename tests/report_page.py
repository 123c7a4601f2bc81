"""Measures of a report page in headless Chromium, for the acceptance tests of issue 22.

Every expression runs through the DevTools protocol (the page itself runs no script: its
Content-Security-Policy forbids it).
"""

from __future__ import annotations

#: Bottom edges (page y, CSS px) of the overview's parts, the page height and the load time.
LAYOUT_JS = """(() => {
  const y = e => e ? Math.round(e.getBoundingClientRect().bottom + window.scrollY) : null;
  const nav = performance.getEntriesByType('navigation')[0];
  return {fleet_map: y(document.querySelector('img.fleet')), matrix: y(document.querySelector('table.matrix')),
          ranked_list: y(document.querySelector('table.top')), height: document.documentElement.scrollHeight,
          width: document.documentElement.scrollWidth, load_ms: nav ? Math.round(nav.loadEventEnd) : null,
          cases: document.querySelectorAll('details.case').length};
})()"""

#: Follow every in-page link: its target exists, its <details> opens, and it is scrolled into view.
ANCHORS_JS = """(async () => {
  const hrefs = [...new Set([...document.querySelectorAll('a[href^="#"]')].map(a => a.getAttribute('href')))];
  const bad = [];
  for (const h of hrefs) {
    const t = document.getElementById(decodeURIComponent(h.slice(1)));
    if (!t) { bad.push([h, 'no such id']); continue; }
    location.hash = h;
    await new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)));
    const d = t.closest('details'), r = t.getBoundingClientRect();
    if ((d && !d.open) || r.height <= 0 || r.top < -2 || r.top > window.innerHeight)
      bad.push([h, {open: d ? d.open : null, top: r.top, height: r.height}]);
  }
  return {links: hrefs.length, bad: bad};
})()"""

#: Under the print style sheet, every <details> folded first (as the page opens): the body of
#: every folded case and section is laid out (visible, not zero height).
PRINT_JS = """(() => {
  document.querySelectorAll('details').forEach(d => { d.open = false; });
  const bodies = [...document.querySelectorAll('details.case > .case-body, details > table, details > div')];
  const closed = [...document.querySelectorAll('details')].filter(d => !d.open).length;
  const hidden = bodies.filter(b => !b.checkVisibility() || b.getBoundingClientRect().height <= 0).length;
  return {folded: closed, bodies: bodies.length, hidden: hidden};
})()"""


def measure(path, chromium, *, width: int = 1400, height: int = 1000, anchors: bool = True, printed: bool = True):
    """Open ``path`` at ``width`` px and return the :class:`dashboards.browser.PageVisit` with
    ``values`` ``layout``, ``anchors`` and ``print`` (see the expressions above)."""
    from dashboards.browser import visit

    evaluate = {"layout": LAYOUT_JS}
    if anchors:
        evaluate["anchors"] = ANCHORS_JS
    return visit(path, chromium=chromium, width=width, height=height, evaluate=evaluate,
                 print_evaluate={"print": PRINT_JS} if printed else None, timeout_s=120.0)
