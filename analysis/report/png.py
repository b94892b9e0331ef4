"""PNG encoding of the report's figures: 8-bit RGB pixels to PNG bytes, in numpy and zlib.

Pillow's encoder tries every PNG filter on every row and keeps the best, which is most
of the cost of writing a 1920 x 1200 figure (~45 ms) and buys nothing on these flat-colour
plots: unfiltered rows at zlib level 1 come out the same size as Pillow's adaptive
filters at level 3, in about a third of the time. The stream is also what the PDF embeds
as it is (:func:`analysis.report.pdf.png_stream`).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

SIGNATURE = b"\x89PNG\r\n\x1a\n"
LEVEL = 1  # zlib level of the pixel stream


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def encode_rgb(rgb: np.ndarray, dpi: float | None = None, level: int = LEVEL) -> bytes:
    """PNG bytes of ``rgb`` (h, w, 3) uint8: 8-bit RGB, not interlaced, every row with
    filter 0 (none); with ``dpi`` (pixels per inch) a pHYs chunk states the resolution."""
    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected (h, w, 3) uint8 pixels, got {rgb.shape} {rgb.dtype}")
    h, w, _ = rgb.shape
    rows = np.zeros((h, 1 + 3 * w), np.uint8)  # column 0: each row's filter byte, 0
    rows[:, 1:] = rgb.reshape(h, 3 * w)
    out = [SIGNATURE, _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))]
    if dpi is not None:
        ppm = round(dpi / 0.0254)  # pixels per metre, unit 1
        out.append(_chunk(b"pHYs", struct.pack(">IIB", ppm, ppm, 1)))
    out += [_chunk(b"IDAT", zlib.compress(rows.data, level)), _chunk(b"IEND", b"")]
    return b"".join(out)
