"""Tests of `lightcal board` (lightcal.capture.board_print, lightcal.io.pdf_file): the PDF's
structure read back byte by byte (no PDF tool on the machine), its page sizes, the marker
images bit for bit and detected by OpenCV, their true size and place, the scale bar."""

from __future__ import annotations

import math
import re
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.capture.apriltag import marker_modules
from lightcal.capture.board_layout import aruco_dictionary
from lightcal.capture.board_print import PAGE_MARGIN_M, board_pages
from lightcal.capture.boards import ArucoGridBoard, LayoutMarker, MarkerLayout
from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.board_file import write_board
from lightcal.io.pdf_file import pdf_bytes

TAG = "DICT_APRILTAG_36h11"
POINTS_PER_M = 72 / 0.0254
LAYOUT = MarkerLayout(
    (
        LayoutMarker(TAG, 0, (-0.6, 0.35), 0.12),
        LayoutMarker(TAG, 1, (0.6, 0.35), 0.1, rotation_deg=30.0),
        LayoutMarker("DICT_4X4_50", 7, (0.0, -0.35), 0.09, rotation_deg=-90.0),
    )
)


def _objects(data: bytes) -> dict[int, bytes]:
    """Object number -> body, checking the cross-reference table's offsets on the way."""
    assert data.startswith(b"%PDF-1.4\n") and data.endswith(b"%%EOF\n")
    startxref = int(re.search(rb"startxref\n(\d+)\n%%EOF\n$", data)[1])
    assert data[startxref:].startswith(b"xref\n")
    head = re.match(rb"xref\n0 (\d+)\n", data[startxref:])
    count = int(head[1])
    table = data[startxref + head.end() :].split(b"\n")[:count]
    assert table[0] == b"0000000000 65535 f "
    objects = {}
    for number, entry in enumerate(table[1:], start=1):
        assert re.fullmatch(rb"\d{10} 00000 n ", entry), entry
        offset = int(entry[:10])
        match = re.match(rb"(\d+) 0 obj\n(.*?)\nendobj\n", data[offset:], re.DOTALL)
        assert match and int(match[1]) == number
        objects[number] = match[2]
    trailer = re.search(rb"trailer\n<< /Size (\d+) /Root (\d+) 0 R >>", data)
    assert int(trailer[1]) == count and b"/Type /Catalog" in objects[int(trailer[2])]
    return objects


def _stream(body: bytes) -> tuple[bytes, bytes]:
    """(dictionary, decoded data) of a stream object."""
    match = re.match(rb"<< (.*) /Length (\d+) >>\nstream\n", body, re.DOTALL)
    assert match
    raw = body[match.end() : match.end() + int(match[2])]
    assert body[match.end() + int(match[2]) :] == b"\nendstream"
    return match[1], zlib.decompress(raw)


def _pages(data: bytes) -> list[tuple[list[float], str, dict[str, tuple[bytes, np.ndarray]]]]:
    """Per page: its MediaBox, its content and its images (dictionary, pixels) by name."""
    objects = _objects(data)
    out = []
    for body in objects.values():
        if not body.startswith(b"<< /Type /Page "):
            continue
        box = [float(v) for v in re.search(rb"/MediaBox \[([^\]]*)\]", body)[1].split()]
        content = _stream(objects[int(re.search(rb"/Contents (\d+) 0 R", body)[1])])[1]
        images = {}
        for name, ref in re.findall(rb"/(Im\d+) (\d+) 0 R", body):
            dictionary, pixels = _stream(objects[int(ref)])
            width = int(re.search(rb"/Width (\d+)", dictionary)[1])
            height = int(re.search(rb"/Height (\d+)", dictionary)[1])
            assert b"/ColorSpace /DeviceGray /BitsPerComponent 8" in dictionary
            image = np.frombuffer(pixels, np.uint8).reshape(height, width)
            images[name.decode()] = (dictionary, image)
        out.append((box, content.decode("latin-1"), images))
    return out


def _cm(content: str) -> list[float]:
    return [
        float(v)
        for v in re.search(r"q (\S+) (\S+) (\S+) (\S+) (\S+) (\S+) cm /Im0 Do Q", content).groups()
    ]


def test_a_page_per_marker_true_size_bit_for_bit_and_detected():
    pages = _pages(pdf_bytes(board_pages(LAYOUT, paper="a4", name="wall.yaml")))
    assert len(pages) == 3
    for k, (box, content, images) in enumerate(pages):
        marker = LAYOUT.markers[k]
        assert box == pytest.approx([0, 0, 0.210 * POINTS_PER_M, 0.297 * POINTS_PER_M], abs=1e-4)
        assert box[2:] == pytest.approx([595.2756, 841.8898], abs=1e-4)
        # The image: the marker with its white border of one module, one pixel a module.
        pixels = images["Im0"][1]
        np.testing.assert_array_equal(
            pixels, np.pad(marker_modules(marker.dictionary, marker.id), 1, constant_values=255)
        )
        assert b"/Interpolate false" in images["Im0"][0]
        big = np.pad(np.kron(pixels, np.ones((20, 20), np.uint8)), 40, constant_values=255)
        detector = cv2.aruco.ArucoDetector(aruco_dictionary(marker.dictionary))
        _, ids, _ = detector.detectMarkers(big)
        assert ids is not None and ids.ravel().tolist() == [marker.id]
        # Drawn at true size (black square size_m, so size_m (n + 2) / n with the border),
        # turned by rotation_deg, centred in the area above the text.
        n = pixels.shape[0] - 2
        side = marker.size_m * (n + 2) / n * POINTS_PER_M
        a, b, c, d, e, f = _cm(content)
        theta = math.radians(marker.rotation_deg)
        assert [a, b, c, d] == pytest.approx(
            [side * math.cos(theta), side * math.sin(theta), -side * math.sin(theta),
             side * math.cos(theta)], abs=2e-4,
        )  # fmt: skip
        center = (e + 0.5 * (a + c), f + 0.5 * (b + d))
        assert center[0] == pytest.approx(box[2] / 2, abs=1e-3)
        # The 100 mm scale bar, 0.8 pt thick, from the left margin.
        left = PAGE_MARGIN_M * POINTS_PER_M
        bar = re.search(r"0\.8 w (\S+) (\S+) m (\S+) (\S+) l S", content)
        assert float(bar[1]) == pytest.approx(left, abs=1e-4)
        assert float(bar[3]) - float(bar[1]) == pytest.approx(0.1 * POINTS_PER_M, abs=2e-4)
    assert "(DICT_APRILTAG_36h11 id 0  -  marker 1 of 3 of wall.yaml) Tj" in pages[0][1]
    assert (
        "(Black square 120.0 mm; its centre on the wall at x = -600.0 mm, y = 350.0 mm \\(x "
        "right, y up\\); the ticks mark the lines through it.) Tj"
    ) in pages[0][1]
    assert (
        "(Marker turned 30 deg counterclockwise: tape the page level, its top edge up.) Tj"
        in (pages[1][1])
    )
    assert "(Print at 100 % \\(no fit to page\\): the bar must measure 100.0 mm.) Tj" in pages[2][1]
    assert (
        "(Marker turned 90 deg clockwise: tape the page level, its top edge up.) Tj"
        in (pages[2][1])
    )
    assert "(Marker upright: tape the page level, its top edge up.) Tj" in pages[0][1]


def test_a_grid_is_one_sheet_landscape_when_it_fits_only_so():
    grid = ArucoGridBoard("DICT_4X4_50", 4, 1, 0.04, 0.01, origin_world_m=(-0.095, 0.02))
    ((box, content, images),) = _pages(pdf_bytes(board_pages(grid, paper="a4")))
    # 0.19 m + 2 x 0.04 m margin = 0.27 m wide: A4 only in landscape.
    assert box[2:] == pytest.approx([0.297 * POINTS_PER_M, 0.210 * POINTS_PER_M], abs=1e-4)
    np.testing.assert_array_equal(images["Im0"][1], grid.render(10_000.0).image)
    a, _, _, d, _, _ = _cm(content)
    assert (a, d) == pytest.approx((0.27 * POINTS_PER_M, 0.12 * POINTS_PER_M), abs=2e-4)


def test_too_large_for_the_paper():
    big = MarkerLayout((LayoutMarker(TAG, 0, (0, 0), 0.2),))
    with pytest.raises(InputError) as info:
        board_pages(big, paper="a4")
    assert (info.value.source, info.value.detail) == (
        "paper",
        "markers[0] (DICT_APRILTAG_36h11 id 0) needs 250.0 mm x 250.0 mm of paper inside the "
        "margins and text, more than a4 gives: use tabloid",
    )
    assert len(board_pages(big, paper="a3")) == 1


def test_cli_writes_the_pdf_and_keeps_the_output_conventions(tmp_path: Path, capsys):
    layout = tmp_path / "wall.yaml"
    write_board(LAYOUT, layout)
    out = tmp_path / "wall.pdf"
    assert main(["board", str(layout), "--out", str(out)]) == 0
    assert capsys.readouterr().out == (
        f"3 pages (one per marker, a4) written to {out}: print at 100 % (no fit to page) and "
        "check that each page's bar measures 100 mm\n"
    )
    assert out.read_bytes() == pdf_bytes(board_pages(LAYOUT, paper="a4", name="wall.yaml"))
    assert main(["board", str(layout), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"lightcal board: error: {out}: --out: exists; use --force to replace it\n"
    )
    assert main(["board", str(layout), "--out", str(out), "--force", "--paper", "a3"]) == 0
    assert len(_pages(out.read_bytes())) == 3
    assert main(["board", str(layout), "--out", str(layout), "--force"]) == 2
    assert capsys.readouterr().err.endswith(
        f"{layout}: --out: is the board file, an input of the PDF; write elsewhere\n"
    )
    assert main(["board", str(layout), "--out", str(tmp_path / "wall.png")]) == 2
    assert capsys.readouterr().err == (
        f"lightcal board: error: {tmp_path / 'wall.png'}: --out: unsupported suffix '.png': "
        "expected .pdf\n"
    )
    write_board(MarkerLayout((LayoutMarker(TAG, 0, (0, 0), 0.2),)), layout)
    assert main(["board", str(layout), "--out", str(tmp_path / "big.pdf")]) == 2
    assert capsys.readouterr().err == (
        "lightcal board: error: --paper: markers[0] (DICT_APRILTAG_36h11 id 0) needs 250.0 mm x "
        "250.0 mm of paper inside the margins and text, more than a4 gives: use tabloid\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wall.pdf", "wall.yaml"]
