"""The report's figures enter the PDF as their PNG's own compressed stream, pixel for pixel."""

from __future__ import annotations

import io

import numpy as np
import pypdf
from PIL import Image

from analysis.report.model import Figure
from analysis.report.pdf import _Doc, _figure, png_stream


def _png(rgb: np.ndarray, mode: str = "RGB") -> bytes:
    buf = io.BytesIO()
    Image.fromarray(rgb, mode).save(buf, format="PNG", dpi=(300, 300), compress_level=3)
    return buf.getvalue()


def _pdf_images(pngs: list[bytes]) -> list[np.ndarray]:
    doc = _Doc("t")
    doc.add_page()
    for i, png in enumerate(pngs):
        _figure(doc, Figure(name=f"f{i}", png=png, width=640, height=400, caption="c"))
    reader = pypdf.PdfReader(io.BytesIO(bytes(doc.output())))
    return [np.asarray(im.image.convert("RGB")) for p in reader.pages for im in p.images]


def test_rgb_png_passes_through_and_decodes_to_its_pixels():
    rng = np.random.default_rng(0)
    # smooth areas and noise: PNG's adaptive filters choose different filters per row
    rgb = np.zeros((120, 190, 3), np.uint8)
    rgb[:, :95] = np.linspace(0, 255, 95, dtype=np.uint8)[None, :, None]
    rgb[:, 95:] = rng.integers(0, 256, (120, 95, 3), dtype=np.uint8)
    png = _png(rgb)
    w, h, data = png_stream(png)
    assert (w, h) == (190, 120) and 0 < len(data) < len(png)
    got = _pdf_images([png, png])
    assert len(got) == 2 and all(np.array_equal(g, rgb) for g in got)


def test_other_pngs_go_through_fpdf():
    rgba = np.full((20, 30, 4), 200, np.uint8)
    rgba[..., 3] = 255
    assert png_stream(_png(rgba, "RGBA")) is None
    assert png_stream(b"not a png") is None
    assert np.array_equal(_pdf_images([_png(rgba, "RGBA")])[0], rgba[..., :3])
