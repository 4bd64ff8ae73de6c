"""A board's printable pages at true scale (`lightcal board LAYOUT --out board.pdf`).

A `markers` board (`MarkerLayout`) prints one page per marker, as a user taping markers
on a wall needs: the marker at its true size with its white border of one module (the
official AprilTag image; an ArUco marker's quiet zone), turned on the page as it is on
the wall (so a page taped level, its top edge up, puts the marker at its
`rotation_deg`), short ticks on the lines through its centre, and below it its
dictionary and id, its size, where its centre goes on the wall and a 100 mm scale bar to
check that the printer kept the scale. Any other board prints as one sheet: its
`render` at `SHEET_PX_PER_M` (or the first of `SHEET_FALLBACK_PX_PER_M` at which its
lengths are whole pixels), with the same text and bar.

Pages are a paper size (`PAPER_SIZES_M`), portrait, or landscape for a marker or sheet
that fits only so; one that fits neither way inside `PAGE_MARGIN_M` and the text block is
refused (`InputError` on `paper`, naming the size it needs and the smallest paper that
holds it). The centre ticks are drawn where there is room beside the marker. Lengths
on the page are exact: a marker of `size_m` is drawn `points(size_m)` points wide
(1 point = 0.0254 / 72 m).
"""

from __future__ import annotations

import math

import numpy as np

from lightcal.capture.apriltag import marker_modules
from lightcal.capture.boards import ArucoGridBoard, Board, CharucoBoard, Chessboard, MarkerLayout
from lightcal.errors import InputError
from lightcal.io.pdf_file import PdfImage, PdfPage, image_at, line, points, text

__all__ = [
    "PAGE_MARGIN_M",
    "PAPER_SIZES_M",
    "SCALE_BAR_M",
    "board_pages",
]

PAPER_SIZES_M = {
    "a4": (0.210, 0.297),
    "a3": (0.297, 0.420),
    "a2": (0.420, 0.594),
    "a1": (0.594, 0.841),
    "a0": (0.841, 1.189),
    "letter": (0.2159, 0.2794),
    "tabloid": (0.2794, 0.4318),
}
"""Paper (width, height) in metres, portrait."""

PAGE_MARGIN_M = 0.006
"""Blank border of every page: most printers cannot print closer to the edge."""

SCALE_BAR_M = 0.1
"""The scale bar's length: it must measure this on the printed page."""

_TEXT_BLOCK_M = 0.042
"""Height of the text and scale bar at the bottom of a page."""

_TICK_GAP_M = 0.001
_TICK_LENGTH_M = 0.008
_MIN_TICK_M = 0.002
"""The centre ticks: this far from the marker's white border, at most this long, drawn
when at least `_MIN_TICK_M` fits before the page's margin."""

_FONT_PT = 8.5
_LINE_PT = 11.0

SHEET_PX_PER_M = 10_000.0
"""Scale of a sheet's image: 0.1 mm a pixel (finer than a printer's registration)."""

SHEET_FALLBACK_PX_PER_M = (20_000.0, 8_000.0, 5_000.0, 4_000.0, 2_000.0, 1_000.0)
"""Scales tried, in order, when a board's lengths are not whole pixels at `SHEET_PX_PER_M`."""


def _mm(value_m: float) -> str:
    return f"{1000.0 * value_m:.1f} mm"


def _footer(lines: list[str]) -> str:
    """The text lines (top to bottom) and the scale bar at the bottom of a page, points."""
    left = points(PAGE_MARGIN_M)
    bar_y = left + 4.0
    bar = points(SCALE_BAR_M)
    ops = line(left, bar_y, left + bar, bar_y, 0.8)
    for k in range(11):  # a tick each centimetre, longer at 0, 5 and 10 cm
        x = left + bar * k / 10.0
        ops += line(x, bar_y, x, bar_y + (6.0 if k % 5 == 0 else 3.0), 0.5)
    ops += text(left + bar + 6.0, bar_y, _FONT_PT, f"{_mm(SCALE_BAR_M)}: measure it")
    y = bar_y + 6.0 + _LINE_PT * len(lines)
    for value in lines:
        ops += text(left, y, _FONT_PT, value)
        y -= _LINE_PT
    return ops


def _page(paper: str, need_w: float, need_h: float) -> tuple[float, float] | None:
    """(width, height) of `paper`, portrait or else landscape, whose area above the text
    holds `need_w` x `need_h` metres; None if neither does."""
    short, long = PAPER_SIZES_M[paper]
    for width, height in ((short, long), (long, short)):
        area_w = width - 2 * PAGE_MARGIN_M
        area_h = height - 2 * PAGE_MARGIN_M - _TEXT_BLOCK_M
        if need_w <= area_w + 1e-12 and need_h <= area_h + 1e-12:
            return width, height
    return None


def _fit(what: str, need_w: float, need_h: float, paper: str) -> tuple[float, float]:
    """The page for `what` (see `_page`), or the InputError on `paper` saying what fits."""
    if paper not in PAPER_SIZES_M:
        raise InputError("paper", f"expected one of {', '.join(PAPER_SIZES_M)}, got {paper!r}")
    page = _page(paper, need_w, need_h)
    if page is not None:
        return page
    by_area = sorted(PAPER_SIZES_M, key=lambda name: math.prod(PAPER_SIZES_M[name]))
    fits = [name for name in by_area if _page(name, need_w, need_h) is not None]
    then = f": use {fits[0]}" if fits else ": print it in parts, no paper here is that large"
    raise InputError(
        "paper",
        f"{what} needs {_mm(need_w)} x {_mm(need_h)} of paper inside the margins and text, "
        f"more than {paper} gives{then}",
    )


def _ticks(cx: float, cy: float, extent: float, area: tuple[float, float, float, float]) -> str:
    """Short lines on the horizontal and vertical through (cx, cy) beside a square of side
    `extent` centred there, inside `area` (x0, y0, x1, y1); metres in, operators out."""
    x0, y0, x1, y1 = area
    start = 0.5 * extent + _TICK_GAP_M
    ops = ""
    for (dx, dy), room in (
        ((1, 0), x1 - cx),
        ((-1, 0), cx - x0),
        ((0, 1), y1 - cy),
        ((0, -1), cy - y0),
    ):
        length = min(_TICK_LENGTH_M, room - start)
        if length >= _MIN_TICK_M:
            ops += line(
                points(cx + dx * start), points(cy + dy * start),
                points(cx + dx * (start + length)), points(cy + dy * (start + length)), 0.6,
            )  # fmt: skip
    return ops


def _marker_pages(layout: MarkerLayout, paper: str, name: str) -> list[PdfPage]:
    pages = []
    for k, marker in enumerate(layout.markers):
        modules = np.pad(marker_modules(marker.dictionary, marker.id), 1, constant_values=255)
        side = marker.size_m * modules.shape[0] / (modules.shape[0] - 2)  # with the border
        theta = math.radians(marker.rotation_deg)
        extent = side * (abs(math.cos(theta)) + abs(math.sin(theta)))
        width, height = _fit(f"markers[{k}] ({marker.describe()})", extent, extent, paper)
        m = PAGE_MARGIN_M
        area = (m, m + _TEXT_BLOCK_M, width - m, height - m)
        cx, cy = 0.5 * (area[0] + area[2]), 0.5 * (area[1] + area[3])
        ops = image_at(
            "Im0", (points(cx), points(cy)), points(side), points(side), marker.rotation_deg
        )
        ops += _ticks(cx, cy, extent, area)
        x, y = marker.center_world_m
        angle = marker.rotation_deg
        turn = (
            "upright"
            if angle == 0.0
            else f"turned {abs(angle):g} deg "
            + ("counterclockwise" if angle > 0.0 else "clockwise")
        )
        lines = [
            f"{marker.describe()}  -  marker {k + 1} of {layout.n_markers} of {name}",
            f"Black square {_mm(marker.size_m)}; its centre on the wall at x = {_mm(x)}, "
            f"y = {_mm(y)} (x right, y up); the ticks mark the lines through it.",
            f"Marker {turn}: tape the page level, its top edge up.",
            f"Print at 100 % (no fit to page): the bar must measure {_mm(SCALE_BAR_M)}.",
        ]
        ops += _footer(lines)
        pages.append(PdfPage(points(width), points(height), ops, (PdfImage("Im0", modules),)))
    return pages


def _sheet_image(board: ArucoGridBoard | CharucoBoard | Chessboard) -> tuple[np.ndarray, float]:
    """The board drawn at the first scale at which its lengths are whole pixels."""
    for px_per_m in (SHEET_PX_PER_M, *SHEET_FALLBACK_PX_PER_M):
        try:
            return board.render(px_per_m).image, px_per_m
        except InputError as exc:
            if exc.source != "px_per_m":
                raise
    raise InputError(
        "board",
        "its lengths are not whole pixels at any of "
        f"{', '.join(f'{s:g}' for s in (SHEET_PX_PER_M, *SHEET_FALLBACK_PX_PER_M))} px/m: "
        "give lengths in whole tenths of a millimetre",
    )


def _sheet_page(
    board: ArucoGridBoard | CharucoBoard | Chessboard, paper: str, name: str
) -> PdfPage:
    if isinstance(board, Chessboard):
        size = (
            (board.inner_x + 1) * board.square_length_m,
            (board.inner_y + 1) * board.square_length_m,
        )
    else:
        size = board.size_m
    image, px_per_m = _sheet_image(board)
    sheet_w, sheet_h = image.shape[1] / px_per_m, image.shape[0] / px_per_m
    width, height = _fit("the board with its white margin", sheet_w, sheet_h, paper)
    cx = 0.5 * width
    cy = 0.5 * (height + _TEXT_BLOCK_M)
    ops = image_at("Im0", (points(cx), points(cy)), points(sheet_w), points(sheet_h), 0.0)
    if isinstance(board, ArucoGridBoard):
        what = (
            f"aruco_grid {board.dictionary}: {board.markers_x} x {board.markers_y} markers of "
            f"{_mm(board.marker_length_m)}, {_mm(board.separation_m)} apart, ids "
            f"{int(board.ids[0])}..{int(board.ids[-1])}"
        )
    elif isinstance(board, CharucoBoard):
        what = (
            f"charuco {board.dictionary}: {board.squares_x} x {board.squares_y} squares of "
            f"{_mm(board.square_length_m)}, markers of {_mm(board.marker_length_m)}"
        )
    else:
        what = (
            f"chessboard: {board.inner_x} x {board.inner_y} inner corners, squares of "
            f"{_mm(board.square_length_m)}"
        )
    if isinstance(board, Chessboard):
        where = "For lightcal camera calibrate: its place on the wall does not matter."
    else:
        x, y = board.origin_world_m
        where = (
            f"Its top-left corner (origin_world_m) on the wall at x = {_mm(x)}, y = {_mm(y)}; "
            f"the print is {_mm(size[0])} x {_mm(size[1])}."
        )
    lines = [
        f"{what}  -  {name}",
        where,
        "Tape the page level, its top edge up (the board's y runs down the page).",
        f"Print at 100 % (no fit to page): the bar must measure {_mm(SCALE_BAR_M)}.",
    ]
    ops += _footer(lines)
    return PdfPage(points(width), points(height), ops, (PdfImage("Im0", image),))


def board_pages(board: Board, *, paper: str = "a4", name: str = "the board") -> list[PdfPage]:
    """The pages that print a board at true scale (module docstring).

    Args:
        board: Any board of `lightcal.capture.boards`.
        paper: A name of `PAPER_SIZES_M`.
        name: How the pages name the board (its file name).

    Returns:
        One page per marker of a `MarkerLayout`, one page for any other board.

    Raises:
        InputError: An unknown paper, or a marker or board too large for it (source
            `paper`, naming the size needed); a board whose lengths are not whole tenths
            of a millimetre (source `board`).
    """
    if isinstance(board, MarkerLayout):
        return _marker_pages(board, paper, name)
    return [_sheet_page(board, paper, name)]
