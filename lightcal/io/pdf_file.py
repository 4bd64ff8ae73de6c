"""A minimal PDF writer: pages of lines, text and grey images, nothing else (no dependency).

`write_pdf(path, pages)` writes PDF 1.4: a catalog, a page tree, the standard Helvetica
font (one of the 14 fonts every reader has, so nothing is embedded), and per page a
content stream and its images. Images are 8-bit grey (`/DeviceGray`) XObjects,
Flate-compressed, drawn without interpolation (`/Interpolate false`), so a marker of a few
modules prints with sharp edges at any size. Lengths are PDF points (1/72 inch), the
origin at the page's bottom-left corner, y up; `points(length_m)` converts metres.

A page's content is PDF operators (`PdfPage.content`); `text`, `line` and `image_at`
write the few a printed board needs.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_bytes

__all__ = [
    "POINTS_PER_M",
    "PdfImage",
    "PdfPage",
    "image_at",
    "line",
    "pdf_bytes",
    "points",
    "text",
    "write_pdf",
]

POINTS_PER_M = 72.0 / 0.0254
"""PDF points per metre (72 points an inch)."""


def points(length_m: float) -> float:
    """A length in metres as PDF points."""
    return length_m * POINTS_PER_M


@dataclass(frozen=True, eq=False)
class PdfImage:
    """A grey image a page draws by name (`image_at`).

    Attributes:
        name: Its resource name on the page, letters and digits (e.g. `"Im0"`).
        pixels: (h, w) uint8, 0 black, 255 white, row 0 at the top.
    """

    name: str
    pixels: NDArray[np.uint8] = field(repr=False)


@dataclass(frozen=True, eq=False)
class PdfPage:
    """One page.

    Attributes:
        width_pt: Page width, points.
        height_pt: Page height, points.
        content: Its content stream (PDF operators).
        images: The images the content draws.
    """

    width_pt: float
    height_pt: float
    content: str
    images: tuple[PdfImage, ...] = ()


def _number(value: float) -> str:
    """A PDF number: fixed point, no exponent, trailing zeros dropped."""
    if not math.isfinite(value):
        raise ValueError(f"not a finite number: {value!r}")
    out = f"{value:.4f}".rstrip("0").rstrip(".")
    return "0" if out in ("-0", "") else out


def _string(value: str) -> str:
    """A PDF literal string of Latin-1 text, (, ) and \\ escaped."""
    value.encode("latin-1")  # Helvetica's encoding here: refuse anything else early
    return "(" + value.replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)") + ")"


def text(x_pt: float, y_pt: float, size_pt: float, value: str) -> str:
    """Operators drawing one line of Helvetica text with its baseline starting at (x, y)."""
    return (
        f"BT /F1 {_number(size_pt)} Tf {_number(x_pt)} {_number(y_pt)} Td {_string(value)} Tj ET\n"
    )


def line(x0_pt: float, y0_pt: float, x1_pt: float, y1_pt: float, width_pt: float) -> str:
    """Operators stroking one black line segment."""
    return (
        f"{_number(width_pt)} w {_number(x0_pt)} {_number(y0_pt)} m "
        f"{_number(x1_pt)} {_number(y1_pt)} l S\n"
    )


def image_at(
    name: str, center_pt: tuple[float, float], width_pt: float, height_pt: float, angle_deg: float
) -> str:
    """Operators drawing an image `width_pt` x `height_pt`, centred at `center_pt` and turned
    counterclockwise by `angle_deg` about its centre (its top row towards +y at 0)."""
    theta = math.radians(angle_deg)
    c, s = math.cos(theta), math.sin(theta)
    # The image's unit square: (0, 0) bottom-left; scaled, centred on 0, turned, moved.
    a, b = width_pt * c, width_pt * s
    cc, d = -height_pt * s, height_pt * c
    e = center_pt[0] - 0.5 * (a + cc)
    f = center_pt[1] - 0.5 * (b + d)
    matrix = " ".join(_number(v) for v in (a, b, cc, d, e, f))
    return f"q {matrix} cm /{name} Do Q\n"


def _stream(dictionary: str, data: bytes) -> bytes:
    head = f"<< {dictionary} /Length {len(data)} >>\nstream\n".encode("latin-1")
    return head + data + b"\nendstream"


def pdf_bytes(pages: Sequence[PdfPage]) -> bytes:
    """The bytes of a PDF of `pages` (at least one).

    Raises:
        InputError: No page, a page of zero or negative size, an image that is not a 2-D
            uint8 array, or an image name that is not letters and digits.
    """
    if not pages:
        raise InputError("pages", "expected at least one page")
    objects: list[bytes] = []  # object k + 1

    def add(body: bytes) -> int:
        objects.append(body)
        return len(objects)

    catalog = add(b"")  # filled in below, once the page tree's number is known
    tree = add(b"")
    font = add(b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica /Encoding /WinAnsiEncoding >>")
    kids = []
    for number, page in enumerate(pages):
        if not (page.width_pt > 0 and page.height_pt > 0):
            raise InputError(f"pages[{number}]", "expected a page of positive size")
        xobjects = []
        for image in page.images:
            pixels = np.asarray(image.pixels)
            if pixels.ndim != 2 or pixels.dtype != np.uint8 or pixels.size == 0:
                raise InputError(image.name, "expected a non-empty 2-D uint8 image")
            if not image.name.isalnum():
                raise InputError(image.name, "expected an image name of letters and digits")
            height, width = pixels.shape
            data = zlib.compress(np.ascontiguousarray(pixels).tobytes(), 9)
            ref = add(
                _stream(
                    f"/Type /XObject /Subtype /Image /Width {width} /Height {height} "
                    "/ColorSpace /DeviceGray /BitsPerComponent 8 /Interpolate false "
                    "/Filter /FlateDecode",
                    data,
                )
            )
            xobjects.append(f"/{image.name} {ref} 0 R")
        content = add(
            _stream("/Filter /FlateDecode", zlib.compress(page.content.encode("latin-1"), 9))
        )
        box = f"[0 0 {_number(page.width_pt)} {_number(page.height_pt)}]"
        resources = f"/Font << /F1 {font} 0 R >>"
        if xobjects:
            resources += f" /XObject << {' '.join(xobjects)} >>"
        kids.append(
            add(
                f"<< /Type /Page /Parent {tree} 0 R /MediaBox {box} /Resources << {resources} >> "
                f"/Contents {content} 0 R >>".encode("latin-1")
            )
        )
    objects[catalog - 1] = f"<< /Type /Catalog /Pages {tree} 0 R >>".encode("latin-1")
    refs = " ".join(f"{k} 0 R" for k in kids)
    objects[tree - 1] = f"<< /Type /Pages /Kids [{refs}] /Count {len(kids)} >>".encode("latin-1")

    out = bytearray(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")
    offsets = []
    for number, body in enumerate(objects, start=1):
        offsets.append(len(out))
        out += f"{number} 0 obj\n".encode("latin-1") + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objects) + 1}\n0000000000 65535 f \n".encode("latin-1")
    for offset in offsets:
        out += f"{offset:010d} 00000 n \n".encode("latin-1")
    out += (
        f"trailer\n<< /Size {len(objects) + 1} /Root {catalog} 0 R >>\nstartxref\n{xref}\n%%EOF\n"
    ).encode("latin-1")
    return bytes(out)


def write_pdf(path: str | Path, pages: Sequence[PdfPage]) -> None:
    """Write a PDF of `pages` atomically.

    Raises:
        InputError: As `pdf_bytes`; or the folder does not exist or cannot be written.
    """
    path = Path(path)
    data = pdf_bytes(pages)
    if not path.parent.is_dir():
        raise InputError(path, f"cannot write: folder {str(path.parent)!r} does not exist")
    try:
        atomic_write_bytes(path, data)
    except OSError as exc:
        raise InputError(path, f"cannot write: {exc.strerror or exc}") from exc
