"""A placement search the job refuses (its output directory holds files) says so in the
page's terms only: the progress line does not repeat the job's line with the command
line's options (--out, --force)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.web.test_plan_view import open_page  # noqa: F401  (the browser page fixture)

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).parents[2]


def test_refused_search_names_the_form_fields(open_page, tmp_path):  # noqa: F811
    ws = tmp_path / "ws"
    (ws / "placement").mkdir(parents=True)
    (ws / "placement" / "old.txt").write_text("an earlier search\n")
    shutil.copy(ROOT / "examples" / "part_circle.csv", ws / "part.csv")
    page = open_page(ws)
    page.click("#tab-use")
    page.wait_for_function("() => [...document.querySelectorAll('#pl-path option')]"
                           ".some((o) => o.value === 'part.csv')", timeout=20_000)
    page.select_option("#pl-path", "part.csv")
    page.click("#pl-run")
    page.wait_for_selector("#view-use[data-place='error']", timeout=60_000)
    shown = page.inner_text("#pl-error") + " " + page.inner_text("#view-use #pl-fields")
    assert "\u201cReplace its files\u201d" in shown
    text = page.inner_text("#pl-text")
    assert "--force" not in text and "--out" not in text, text
    assert (ws / "placement" / "old.txt").read_text() == "an earlier search\n"
