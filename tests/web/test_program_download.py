"""The Use view's compensation: its robot program is downloaded by a click on its link,
under its own name, with the bytes the compensate job wrote."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.web.test_plan_view import open_page  # noqa: F401  (the browser page fixture)

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).parents[2]


def test_compensation_program_downloads(open_page, tmp_path):  # noqa: F811
    ws = tmp_path / "ws"
    ws.mkdir()
    shutil.copy(ROOT / "examples" / "kr240-2_path.csv", ws / "path.csv")
    page = open_page(ws)
    page.click("#tab-use")
    page.wait_for_function("() => [...document.querySelectorAll('#comp-path option')]"
                           ".some((o) => o.value === 'path.csv')", timeout=20_000)
    page.select_option("#comp-path", "path.csv")
    page.select_option("#comp-robot", "kr240-2")
    page.fill("#comp-w-fz", "-1500")
    page.fill("#comp-out", "comp")
    page.click("#comp-run")
    page.wait_for_selector("#view-use[data-comp='done']", timeout=60_000)
    programs = sorted(p.name for p in (ws / "comp").iterdir() if p.suffix in (".src", ".dat"))
    assert programs == ["comp_path.dat", "comp_path.src"]
    for name in programs:
        with page.expect_download() as info:
            page.locator("#comp-files a", has_text=f"comp/{name}").click()
        download = info.value
        assert download.suggested_filename == name
        assert Path(download.path()).read_bytes() == (ws / "comp" / name).read_bytes()
