"""Browser test: a rendered report opened headless from file:// makes no request, logs no error
and is not blank. ``make test`` installs Debian's chromium when it is missing and sets
``STORMLANE_REQUIRE_BROWSER=1``, so there a missing browser fails instead of skipping."""

from __future__ import annotations

import os

import pytest

import _report_fixtures as fx
from dashboards.browser import find_chromium, is_blank_png, visit
from dashboards.report import render_audit_report, render_nightly_report

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def chromium():
    path = find_chromium()
    if path is None:
        if os.environ.get("STORMLANE_REQUIRE_BROWSER") == "1":
            pytest.fail("STORMLANE_REQUIRE_BROWSER=1 but no chromium found (make test installs Debian's 'chromium')")
        pytest.skip("no chromium on PATH (make test installs it; or set STORMLANE_CHROMIUM)")
    return path


def _check_clean(v, path):
    assert v.requests and v.requests[0] == path.resolve().as_uri()
    assert v.requests_leaving() == [], f"requests left file://: {v.requests_leaving()}"
    assert v.errors == [], f"console errors: {v.errors}"
    assert not is_blank_png(v.screenshot_png)


def test_nightly_report_opens_clean_from_file(chromium, tmp_path):
    path = render_nightly_report(fx.nightly(origin="<script>alert(1)</script>"), tmp_path / "night.html")
    v = visit(path, chromium=chromium, full_page=True)
    _check_clean(v, path)
    assert v.title == "stormlane nightly reroute report (TEST FIXTURE)"
    # Inline figures only: every other request is a data: URI (bytes inside the page).
    assert all(u.startswith("data:image/png;base64,") for u in v.requests[1:])
    (tmp_path / "night.png").write_bytes(v.screenshot_png)


def test_audit_report_opens_clean_and_shows_the_name_as_text(chromium, tmp_path):
    from report_page import measure

    path = render_audit_report(fx.audit(ship_name="<script>alert(1)</script>"), tmp_path / "audit.html")
    v = measure(path, chromium)
    _check_clean(v, path)
    assert v.title == "stormlane voyage audit (TEST FIXTURE): <script>alert(1)</script>"  # text, not markup
    # issue 22: the folded sections' links open them; printing lays every folded section out
    assert v.values["anchors"]["links"] == 4 and v.values["anchors"]["bad"] == []
    printed = v.values["print"]
    assert printed["folded"] >= 4 and printed["hidden"] == 0


def test_the_print_check_fails_without_the_print_style(chromium, tmp_path):
    """Negative control of the print check: the same page without the rule that unfolds
    <details> in print has every folded body hidden."""
    from report_page import measure

    text = render_audit_report(fx.audit(), tmp_path / "audit.html").read_text(encoding="utf-8")
    rule = "details::details-content { content-visibility:visible; display:block; }"
    assert rule in text
    bare = tmp_path / "bare.html"
    bare.write_text(text.replace(rule, ""), encoding="utf-8")
    printed = measure(bare, chromium, anchors=False).values["print"]
    assert printed["bodies"] >= 4 and printed["hidden"] == printed["bodies"]


def test_the_check_catches_requests_errors_and_blank_pages(chromium, tmp_path):
    """Negative control: the same checks fail on a page that fetches, logs an error, or is blank."""
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><body><img src="http://tiles.example.invalid/1.png"><script>console.error("boom")</script></body></html>')
    v = visit(bad, chromium=chromium)
    assert "http://tiles.example.invalid/1.png" in v.requests_leaving()
    assert any("boom" in e for e in v.errors)
    assert is_blank_png(v.screenshot_png)
