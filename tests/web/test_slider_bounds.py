"""Every slider of the sensitivity explorer, pushed to both ends with the keyboard, sends a
value the API accepts: the page's slider ranges are the request schema's bounds (an
optional field's bounds sit in its ``anyOf``), and the numbers shown are the job's."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.web.test_browser import (  # noqa: F401  (the browser page fixture)
    _assert_page_equals_job,
    _wait_shown,
    page,
)

pytestmark = pytest.mark.timeout(120)


def _bounds(schema: dict) -> tuple[float | None, float | None]:
    for s in schema.get("anyOf", [schema]):
        if s.get("type") in ("number", "integer"):
            return s.get("minimum"), s.get("maximum")
    return None, None


def _press(pg, key: str, button: str) -> None:
    before = int(pg.evaluate("() => document.body.dataset.updates || '0'"))
    slider = pg.locator(f"#s-{key}")
    slider.focus()
    slider.press(button)
    pg.wait_for_function(
        f"() => Number(document.body.dataset.updates) > {before}"
        " || (document.body.dataset.shown || '').startsWith('error:')", timeout=60_000)
    pg.wait_for_function("() => (document.body.dataset.shown || '').replace(/^error:/, '')"
                           " === JSON.stringify(body())", timeout=60_000)


def test_reflector_radius_slider_stays_inside_the_api_bounds(page, workspace: Path):  # noqa: F811
    schema = page.evaluate("() => fetch('/openapi.json').then((r) => r.json())")
    props = schema["components"]["schemas"]["SensitivityRequest"]["properties"]
    lo, hi = _bounds(props["reflector_radius_mm"])
    assert lo == 10  # mm: the triangle of reflectors can be no smaller
    page.select_option("#rotation-from", "reflectors")
    _wait_shown(page)
    for button in ("Home", "End", "Home"):
        _press(page, "reflector_radius_mm", button)
        assert page.locator("#sens-error").inner_text() == ""
        body = _assert_page_equals_job(page, workspace)
        value = float(page.locator("#s-reflector_radius_mm").input_value())
        assert body["reflector_radius_mm"] == value
        assert value == (lo if button == "Home" else min(500, hi))
    # every slider's range lies inside its field's bounds
    for key in page.evaluate("() => [...document.querySelectorAll('#sliders input[type=range]')]"
                             ".map((s) => s.name)"):
        smin = float(page.locator(f"#s-{key}").get_attribute("min"))
        smax = float(page.locator(f"#s-{key}").get_attribute("max"))
        flo, fhi = _bounds(props[key])
        assert flo is None or smin >= flo, key
        assert fhi is None or smax <= fhi, key
