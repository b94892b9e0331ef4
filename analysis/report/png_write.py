"""PNG bytes of an 8-bit grey or RGB image, written here: every row with PNG's "Up"
filter (the difference from the row above, modulo 256), one zlib stream, the
resolution in a pHYs chunk.

Why not Pillow: its PNG writer chooses a filter for each row by trying all five
(adaptive filtering), which was 33 of its 42 ms for a 1920 x 1200 report figure even
with no compression at all; the Up filter alone, in numpy, and zlib at level 3 take
12 ms. Files: the demo report's six figures 2 % larger in all (each -2 to +17 %).
Same pixels. The chunks are those
:mod:`analysis.report.pdf_png` passes to the PDF as they are (IHDR, pHYs, IDAT, IEND).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: PNG filter type of each row: 0 none (the first row: no row above), 2 Up
FILTER_NONE, FILTER_UP = 0, 2


def _chunk(kind: bytes, body: bytes) -> bytes:
    return (struct.pack(">I", len(body)) + kind + body
            + struct.pack(">I", zlib.crc32(kind + body)))


def png_bytes(pixels: np.ndarray, dpi: float, level: int = 3) -> bytes:
    """The PNG of ``pixels``: (h, w) uint8 grey levels or (h, w, 3) uint8 RGB, with a
    resolution of ``dpi`` pixels per inch (stored as pixels per metre, rounded) and
    zlib ``level`` (0-9)."""
    px = np.asarray(pixels)
    if px.dtype != np.uint8 or px.ndim not in (2, 3) or (px.ndim == 3 and px.shape[2] != 3):
        raise ValueError(f"expected (h, w) or (h, w, 3) uint8 pixels, got {px.dtype} "
                         f"{px.shape}")
    h, w = px.shape[:2]
    samples = 3 if px.ndim == 3 else 1
    filtered = np.empty((h, w * samples + 1), dtype=np.uint8)
    # each row's samples after its filter byte, shaped as the pixels: a view (splitting
    # the row's last axis), so a strided ``pixels`` (the RGB of an RGBA buffer) is read
    # once, into it, with no contiguous copy first
    body = filtered[:, 1:].reshape(px.shape)
    if not np.shares_memory(body, filtered):  # never: numpy splits a contiguous axis in place
        raise RuntimeError("the PNG rows' view is a copy")
    filtered[0, 0] = FILTER_NONE
    body[0] = px[0]
    filtered[1:, 0] = FILTER_UP
    np.subtract(px[1:], px[:-1], out=body[1:])  # uint8: modulo 256
    colour = 2 if px.ndim == 3 else 0
    per_metre = int(dpi / 0.0254 + 0.5)
    return (SIGNATURE
            + _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0))
            + _chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1))
            + _chunk(b"IDAT", zlib.compress(filtered.tobytes(), level))
            + _chunk(b"IEND", b""))
