"""The report's own PNG writer (analysis/report/png_write.py): the pixels read back by an
independent decoder (Pillow), the resolution, the Up filter, and the PDF's pass-through."""

from __future__ import annotations

import io
import zlib

import numpy as np
import pytest
from PIL import Image

from analysis.report.pdf_png import png_stream
from analysis.report.png_write import png_bytes


@pytest.mark.parametrize("shape", [(37, 53, 3), (37, 53), (1, 9, 3), (5, 1)])
def test_pixels_read_back_by_pillow(shape):
    rng = np.random.default_rng(7)
    px = rng.integers(0, 256, size=shape, dtype=np.uint8)
    px[..., 0] = 255 - px[..., 0]  # large steps both ways: the Up filter wraps modulo 256
    png = png_bytes(px, 300)
    image = Image.open(io.BytesIO(png))
    assert image.mode == ("RGB" if len(shape) == 3 else "L")
    np.testing.assert_array_equal(np.asarray(image), px)
    # 300 px per inch stored as 11811 px per metre, read back as 299.9994
    assert image.info["dpi"] == pytest.approx((300, 300), abs=1e-3)


def test_strided_rgb_view_of_an_rgba_buffer():
    rng = np.random.default_rng(8)
    rgba = rng.integers(0, 256, size=(20, 30, 4), dtype=np.uint8)
    view = rgba[..., :3]
    assert not view.flags.c_contiguous
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(png_bytes(view, 72)))),
                                  view)


def test_up_filter_rows_and_pdf_pass_through():
    px = np.tile(np.arange(8, dtype=np.uint8) * 30, (4, 1))  # every row the same
    width, height, space, samples, data = png_stream(png_bytes(px, 300))
    assert (width, height, space, samples) == (8, 4, "DeviceGray", 1)
    rows = np.frombuffer(zlib.decompress(data), dtype=np.uint8).reshape(4, 9)
    assert rows[0, 0] == 0 and np.array_equal(rows[0, 1:], px[0])  # first row: no filter
    assert np.all(rows[1:, 0] == 2) and not rows[1:, 1:].any()  # Up: zero differences


@pytest.mark.parametrize("bad", [np.zeros((4, 4)), np.zeros((4, 4, 4), np.uint8),
                                 np.zeros(4, np.uint8)])
def test_refuses_what_it_does_not_write(bad):
    with pytest.raises(ValueError, match="uint8 pixels"):
        png_bytes(bad, 300)
