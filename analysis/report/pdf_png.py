"""A report figure's PNG placed in the PDF as it is: its compressed pixel data is the
image stream, nothing decoded or compressed again.

A PNG's IDAT data (zlib, each row prefixed with its filter byte) is what a PDF image
stream with ``/FlateDecode`` and ``/DecodeParms << /Predictor 15 /Colors c /Columns w
>>`` reads (PDF 32000-1, 7.4.4.4), for the PNGs PDF can describe that way: 8 bits per
sample, grey or RGB, no alpha, no palette, not interlaced, which is what
:func:`analysis.report.figures._png` writes. fpdf2 re-encodes any PNG it is given
(decode, then zlib again: 0.32 s of the demo report's 0.6 s of PDF); its image cache
(``FPDF.image_cache.images``, which ``FPDF.image`` consults by name before reading an
image, as fpdf2's ``preload_image`` documents) takes the image's description instead.
Any other PNG goes to fpdf2 the ordinary way.
"""

from __future__ import annotations

import hashlib
import struct
import zlib

SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: PNG colour type -> (PDF colour space, samples per pixel), for the types passed as they are
COLOUR_TYPES = {0: ("DeviceGray", 1), 2: ("DeviceRGB", 3)}


def png_stream(png: bytes) -> tuple[int, int, str, int, bytes] | None:
    """(width, height, colour space, samples per pixel, IDAT data) of a PNG a PDF can
    take as it is, or None (another kind of PNG, or not a well-formed one)."""
    if not png.startswith(SIGNATURE):
        return None
    pos, header, data = len(SIGNATURE), None, []
    while pos + 8 <= len(png):
        length, kind = struct.unpack(">I4s", png[pos:pos + 8])
        body = png[pos + 8:pos + 8 + length]
        crc = png[pos + 8 + length:pos + 12 + length]
        if len(body) != length or len(crc) != 4 or \
                zlib.crc32(kind + body) != struct.unpack(">I", crc)[0]:
            return None
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            data.append(body)
        elif kind == b"IEND":
            break
        elif kind in (b"tRNS", b"PLTE", b"iCCP", b"gAMA", b"cHRM", b"sRGB"):
            return None  # transparency, palette or colour management: fpdf2 decides
        pos += 12 + length
    if header is None or not data:
        return None
    width, height, depth, colour, _compression, _filter, interlace = header
    if depth != 8 or interlace != 0 or colour not in COLOUR_TYPES:
        return None
    space, samples = COLOUR_TYPES[colour]
    return width, height, space, samples, b"".join(data)


def place_png(doc, png: bytes):
    """The name to give ``doc.image`` for ``png``: a name of ``doc``'s image cache holding
    the PNG's own compressed data, or a file-like of the PNG where it cannot be passed
    as it is (fpdf2 then decodes and re-encodes it)."""
    import io

    try:
        from fpdf.image_datastructures import RasterImageInfo
    except ImportError:  # an fpdf2 without this record: the ordinary way
        return io.BytesIO(png)

    stream = png_stream(png)
    if stream is None or not hasattr(doc, "image_cache"):
        return io.BytesIO(png)
    width, height, space, samples, data = stream
    name = "report-png-" + hashlib.sha256(png).hexdigest()
    cache = doc.image_cache.images
    if name in cache:
        return name  # fpdf2 counts the reuse
    info = RasterImageInfo(
        data=data, w=width, h=height, cs=space, iccp=None, dpn=samples, bpc=8,
        f="FlateDecode", inverted=False,
        dp=f"/Predictor 15 /Colors {samples} /Columns {width}")
    info["i"] = len(cache) + 1
    info["usages"] = 0  # FPDF.image counts this use
    info["iccp_i"] = None
    cache[name] = info
    return name
