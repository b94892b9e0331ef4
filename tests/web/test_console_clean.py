"""The page runs clean under its Content Security Policy: no inline handler in the static
files, and a real headless Chromium (Debian's ``chromium``) that opens every view logs no
console error, CSP violation or uncaught exception; Enter in a form does not reload it."""

from __future__ import annotations

import re
from pathlib import Path

from tests.web.conftest import VIEWPORT

STATIC = Path(__file__).parents[2] / "campaign" / "web" / "static"
#: an inline event handler attribute (onsubmit="...", onclick='...'), which script-src 'self'
#: blocks
INLINE = re.compile(r"""<[^>]*\son[a-z]+\s*=\s*["']""", re.IGNORECASE)
VIEWS = ("sensitivity", "runs", "use", "acquire", "plan", "fleet")


def test_no_inline_handlers_in_static_files():
    files = [p for p in STATIC.rglob("*") if p.suffix in (".html", ".js")
             and "vendor" not in p.parts]
    assert len(files) >= 5
    hits = [f"{p.relative_to(STATIC)}:{i}" for p in files
            for i, line in enumerate(p.read_text().splitlines(), 1) if INLINE.search(line)]
    assert hits == []


def test_inline_pattern_catches_a_handler():
    assert INLINE.search('<form id="f" onsubmit="return false">')
    assert not INLINE.search('<form id="f" autocomplete="off">')


def test_every_view_loads_without_console_error(server, browser):
    errors: list[str] = []
    context = browser.new_context(viewport=VIEWPORT)
    try:
        page = context.new_page()
        page.on("console", lambda m: errors.append(f"console: {m.text}")
                if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(f"pageerror: {e}"))
        page.on("response", lambda r: errors.append(f"{r.status} {r.url}")
                if r.status >= 400 else None)
        page.goto(server)
        page.wait_for_selector("#row-k6", timeout=30_000)
        for view in VIEWS:
            page.click(f"#tab-{view}")
            page.wait_for_selector(f"#view-{view}", state="visible")
            page.wait_for_timeout(400)  # an error the view logs after it shows
        # Enter in a field of a form: the page stays (no submit, no reload)
        page.click("#tab-plan")
        page.evaluate("() => { window.__stay = 1; }")
        page.locator("#plan-form input").first.press("Enter")
        page.wait_for_timeout(300)
        assert page.evaluate("() => window.__stay") == 1
    finally:
        context.close()
    assert errors == []


def test_acquire_state_before_any_run_is_204_not_an_error(client):
    assert client.get("/api/acquire/state").status_code == 204
