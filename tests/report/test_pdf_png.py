"""Report figures go into the PDF as their PNG's own compressed data (issue 36): the PDF
shows the same pixels, and its image stream is the PNG's IDAT data byte for byte."""

from __future__ import annotations

import io

import numpy as np
import pytest
from fpdf import FPDF
from PIL import Image
from pypdf import PdfReader

from analysis.report.pdf_png import place_png, png_stream


def _png(pixels: np.ndarray, mode: str | None = None) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(pixels, mode).save(buf, format="PNG", dpi=(300, 300), compress_level=3)
    return buf.getvalue()


def _pixels(shape, seed):
    """Smooth gradients plus noise (every PNG row filter gets used), uint8."""
    y, x = np.mgrid[0:shape[0], 0:shape[1]]
    base = x * 3 + y * 5
    if len(shape) == 3:
        base = base[..., None] + 70 * np.arange(shape[2])
    noise = np.random.default_rng(seed).integers(0, 40, size=shape)
    return ((base + noise) % 256).astype(np.uint8)


@pytest.mark.parametrize("shape", [(37, 53), (40, 61, 3)])
def test_pdf_image_is_the_png_pixels_and_its_idat_bytes(shape):
    pixels = _pixels(shape, 1)
    png = _png(pixels)
    stream = png_stream(png)
    assert stream is not None
    width, height, space, samples, data = stream
    assert (width, height) == (shape[1], shape[0])
    assert (space, samples) == (("DeviceGray", 1) if len(shape) == 2 else ("DeviceRGB", 3))
    doc = FPDF()
    doc.add_page()
    name = place_png(doc, png)
    assert isinstance(name, str)
    doc.image(name, x=10, y=10, w=100)
    doc.image(place_png(doc, png), x=10, y=120, w=100)  # the same figure twice: one object
    reader = PdfReader(io.BytesIO(bytes(doc.output())))
    images = reader.pages[0].images
    assert len({img.indirect_reference.idnum for img in images}) == 1
    obj = images[0].indirect_reference.get_object()
    assert obj.get_data() != b""  # decodable
    assert obj._data == data  # the stream is the PNG's compressed data, unchanged
    np.testing.assert_array_equal(np.asarray(images[0].image), pixels)


def test_other_pngs_go_to_fpdf2_decoded():
    rgba = np.dstack([_pixels((20, 30, 3), 2), np.full((20, 30), 128, np.uint8)])
    for png in (_png(rgba), _png(_pixels((20, 30), 3)).replace(b"IDAT", b"IDAX", 1),
                b"not a png"):
        assert png_stream(png) is None
    doc = FPDF()
    doc.add_page()
    placed = place_png(doc, _png(rgba))
    assert isinstance(placed, io.BytesIO)
    doc.image(placed, x=10, y=10, w=50)
    assert len(PdfReader(io.BytesIO(bytes(doc.output()))).pages[0].images) == 1
