"""Tests of lightcal.io.ies: IES LM-63 files of every vintage and symmetry, errors, round trips."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.core.rid import SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.eulumdat import read_ldt
from lightcal.io.ies import read_ies, write_ies
from lightcal.io.photometric_table import PhotometricTable, expand_full, table_to_rid

DATA = Path(__file__).parent / "data" / "photometry"


def f(rid, theta_deg, c_deg=0.0) -> float:
    """The RID at vertical angle gamma = theta and horizontal angle C (phi = -C): the
    table's exact interpolation (the renderer's grid: tests/test_rid_grid.py)."""
    theta, phi = np.array(math.radians(theta_deg)), np.array(math.radians(-c_deg))
    return float(rid.value_and_derivatives(theta, phi, exact=True)[0])


def error_text(call) -> str:
    with pytest.raises(InputError) as info:
        call()
    return str(info.value)


# --------------------------------------------------------------------------- the data files


def test_axial_lm63_2002():
    t = read_ies(DATA / "axial_2002.ies")
    assert t.symmetry == "axial"
    assert t.source == str(DATA / "axial_2002.ies")
    assert t.luminaire == "Axial downlight with a frosted lens"  # [LUMINAIRE] + [MORE]
    assert t.lamp_lumens == 1000.0
    assert t.multiplier == 2.0  # candela multiplier 2, ballast factor 1
    np.testing.assert_array_equal(t.vertical_deg, [0, 30, 60, 90])
    np.testing.assert_array_equal(t.horizontal_deg, [0])
    np.testing.assert_array_equal(t.candela, [[200, 160, 80, 0]])
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, [0])
    np.testing.assert_array_equal(cd, [[200, 160, 80, 0]])
    rid = table_to_rid(t)
    assert isinstance(rid, SymmetricTableRID)
    assert f(rid, 30, 250) == pytest.approx(0.8)
    assert f(rid, 60) == pytest.approx(0.4)
    assert f(rid, 120) == 0.0


def test_quadrant_lm63_1995_applies_the_ballast_lamp_factor():
    t = read_ies(DATA / "quadrant_1995.ies")
    assert t.symmetry == "quadrant"
    assert t.multiplier == 0.5  # 1 x ballast factor 1 x ballast-lamp photometric factor 0.5
    assert t.lamp_lumens == 1000.0  # 2 lamps x 500 lm
    assert t.luminaire == "Quadrant"
    np.testing.assert_array_equal(t.vertical_deg, [0, 45, 90])
    np.testing.assert_array_equal(t.horizontal_deg, [0, 45, 90])
    np.testing.assert_array_equal(t.candela, [[100, 50, 10], [100, 60, 20], [100, 70, 30]])
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, [0, 45, 90, 135, 180, 225, 270, 315])
    np.testing.assert_array_equal(cd[:, 1], [50, 60, 70, 60, 50, 60, 70, 60])
    np.testing.assert_array_equal(cd[:, 2], [10, 20, 30, 20, 10, 20, 30, 20])
    rid = table_to_rid(t)
    assert isinstance(rid, Table2DRID)
    assert f(rid, 45, 135) == pytest.approx(0.6)
    assert f(rid, 45, 270) == pytest.approx(0.7)
    assert f(rid, 90, 180) == pytest.approx(0.1)
    assert f(rid, 30, 200) == pytest.approx(f(rid, 30, 160), rel=1e-12)
    assert f(rid, 30, 200) == pytest.approx(f(rid, 30, 20), rel=1e-12)


def test_bilateral_0_180_lm63_2019():
    t = read_ies(DATA / "bilateral_0_180_2019.ies")
    assert t.symmetry == "bilateral_0_180"
    assert t.multiplier == 1.0  # the file generation type 1.1 is not a multiplier
    assert t.lamp_lumens is None  # absolute photometry (-1 lumens per lamp)
    np.testing.assert_array_equal(t.horizontal_deg, [0, 20, 90, 160, 180])
    np.testing.assert_array_equal(
        t.candela, [[10, 8, 4], [10, 7, 3], [10, 6, 2], [10, 5, 1], [10, 4, 0]]
    )
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, [0, 20, 90, 160, 180, 200, 270, 340])
    np.testing.assert_array_equal(cd[:, 1], [8, 7, 6, 5, 4, 5, 6, 7])
    rid = table_to_rid(t)
    assert f(rid, 45, 200) == pytest.approx(0.5)
    assert f(rid, 45, 160) == pytest.approx(0.5)
    assert f(rid, 90, 270) == pytest.approx(0.2)
    assert f(rid, 45, 340) == pytest.approx(0.7)
    assert f(rid, 30, 250) == pytest.approx(f(rid, 30, 110), rel=1e-12)


def test_bilateral_90_270_lm63_1991():
    t = read_ies(DATA / "bilateral_90_270_1991.ies")
    assert t.symmetry == "bilateral_90_270"
    assert t.luminaire == "Bilateral 90-270"
    np.testing.assert_array_equal(t.horizontal_deg, [90, 135, 180, 225, 270])
    np.testing.assert_array_equal(
        t.candela, [[50, 40, 30], [50, 35, 20], [50, 30, 10], [50, 25, 5], [50, 20, 0]]
    )
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, [0, 45, 90, 135, 180, 225, 270, 315])
    # I(C) = I(180 - C): 0 <- 180, 45 <- 135, 315 <- 225.
    np.testing.assert_array_equal(cd[:, 1], [30, 35, 40, 35, 30, 25, 20, 25])
    rid = table_to_rid(t)
    assert f(rid, 45, 45) == pytest.approx(0.7)
    assert f(rid, 45, 315) == pytest.approx(0.5)
    assert f(rid, 90, 0) == pytest.approx(0.2)
    assert f(rid, 30, 20) == pytest.approx(f(rid, 30, 160), rel=1e-12)


def test_no_symmetry_headerless_lm63_1986():
    t = read_ies(DATA / "none_1986.ies")
    assert t.symmetry == "none"
    assert t.luminaire == ""
    assert t.multiplier == 2.0  # ballast-lamp photometric factor 2 (1986 form)
    np.testing.assert_array_equal(t.horizontal_deg, [0, 90, 180, 270, 360])
    np.testing.assert_array_equal(
        t.candela, [[80, 60, 40], [80, 40, 20], [80, 20, 0], [80, 50, 30], [80, 60, 40]]
    )
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, [0, 90, 180, 270])
    np.testing.assert_array_equal(cd, t.candela[:4])
    rid = table_to_rid(t)
    assert f(rid, 45, 90) == pytest.approx(0.5)
    assert f(rid, 45, 180) == pytest.approx(0.25)
    assert f(rid, 45, 270) == pytest.approx(0.625)
    assert f(rid, 90, 270) == pytest.approx(0.375)
    assert f(rid, 45, 360) == pytest.approx(0.75)


def test_numbers_wrapped_across_lines_and_comma_separated():
    t = read_ies(DATA / "wrapped_2002.ies")
    assert t.symmetry == "quadrant"
    assert t.multiplier == 1.0
    assert t.lamp_lumens == 1000.0
    np.testing.assert_array_equal(t.vertical_deg, [0, 45, 90])
    np.testing.assert_array_equal(t.horizontal_deg, [0, 45, 90])
    np.testing.assert_array_equal(t.candela, [[200, 100, 20], [200, 120, 40], [200, 140, 60]])


def test_uplight_reads_but_has_no_rid(tmp_path):
    path = tmp_path / "up.ies"
    path.write_text(
        "IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 3 1 1 2 0 0 0\n1 1 0\n90 135 180\n0\n0 5 10\n"
    )
    t = read_ies(path)
    np.testing.assert_array_equal(t.vertical_deg, [90, 135, 180])
    assert error_text(lambda: table_to_rid(t)) == (
        f"{path}: vertical angles start at 90 degrees: expected the table to start at gamma 0 "
        "(the light axis); uplight tables (vertical angles 90..180) are not supported"
    )


# --------------------------------------------------------------------------- malformed files

BASE = (
    "IESNA:LM-63-2002\n"  # 1
    "[TEST] T\n"  # 2
    "TILT=NONE\n"  # 3
    "1 1000 1 3 2 1 2 0 0 0\n"  # 4
    "1 1 10\n"  # 5
    "0 45 90\n"  # 6
    "0 180\n"  # 7
    "100 50 10\n"  # 8
    "100 40 5\n"  # 9
)
DEMAND = "(the counts, 2 horizontal x 3 vertical angles, demand 24 numbers after TILT=NONE, found"


def replace_line(text: str, number: int, new: str | None) -> str:
    lines = text.splitlines()
    if new is None:
        del lines[number - 1]
    else:
        lines[number - 1] = new
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    ("number", "new", "line", "message"),
    [
        # truncated tables: the last line
        (
            9,
            None,
            8,
            "unexpected end of file: expected candela value 1 of 3 at horizontal angle 180 "
            f"{DEMAND} 21)",
        ),
        (
            9,
            "100 40",
            9,
            "unexpected end of file: expected candela value 3 of 3 at horizontal angle 180 "
            f"{DEMAND} 23)",
        ),
        # mismatched counts
        (
            9,
            "100 40 5 7",
            9,
            "unexpected '7' after the candela table: the counts, 2 horizontal x 3 vertical angles, "
            "demand 24 numbers after TILT=NONE, found 25",
        ),
        (
            4,
            "1 1000 1 3 3 1 2 0 0 0",
            8,
            "horizontal angle 3 of 3 (100) is not greater than the previous one (180): "
            "expected strictly increasing angles",
        ),
        # values
        (
            9,
            "100 -40 5",
            9,
            "candela value 2 of 3 at horizontal angle 180 is negative (-40): expected values >= 0",
        ),
        (
            6,
            "0 45 45",
            6,
            "vertical angle 3 of 3 (45) is not greater than the previous one (45): "
            "expected strictly increasing angles",
        ),
        (6, "0 45 190", 6, "vertical angle 3 of 3 is 190: expected angles in [0, 180] degrees"),
        (
            8,
            "100 5O 10",
            8,
            "candela value 2 of 3 at horizontal angle 0: expected a number, got '5O'",
        ),
        (
            8,
            "nan 50 10",
            8,
            "candela value 1 of 3 at horizontal angle 0: expected a finite number, got 'nan'",
        ),
        (
            4,
            "1 1000 1 2.5 2 1 2 0 0 0",
            4,
            "number of vertical angles 2.5: expected an integer >= 2",
        ),
        (4, "1 1000 0 3 2 1 2 0 0 0", 4, "candela multiplier 0: expected a value > 0"),
        (5, "0 1 10", 5, "ballast factor 0: expected a value > 0"),
        # photometric type
        (
            4,
            "1 1000 1 3 2 2 2 0 0 0",
            4,
            "photometric type 2 (type B) is not supported: expected 1 (type C)",
        ),
        (
            4,
            "1 1000 1 3 2 3 2 0 0 0",
            4,
            "photometric type 3 (type A) is not supported: expected 1 (type C)",
        ),
        # horizontal-angle sets
        (
            7,
            "0 270",
            7,
            "horizontal angles 0..270: expected 0 (axial symmetry), 0..90 (quadrant), 0..180 "
            "(bilateral about the 0-180 plane), 90..270 (bilateral about the 90-270 plane) or "
            "0..360 (no symmetry)",
        ),
        # tilt, header
        (3, "TILT=INCLUDE", 3, "TILT=INCLUDE: tilt tables are not supported; expected TILT=NONE"),
        (3, "TILT=lamp.tlt", 3, "TILT=lamp.tlt: tilt tables are not supported; expected TILT=NONE"),
        (3, None, 8, "no TILT= line: expected TILT=NONE after the header and keyword lines"),
        (
            1,
            "IESNA:LM-63-2020",
            1,
            "unknown header 'IESNA:LM-63-2020': expected IESNA:LM-63-1995, IESNA:LM-63-2002, "
            "IES:LM-63-2019, IESNA91, or no header (LM-63-1986)",
        ),
    ],
)
def test_malformed_files_name_the_line(tmp_path, number, new, line, message):
    path = tmp_path / "bad.ies"
    path.write_text(replace_line(BASE, number, new))
    assert error_text(lambda: read_ies(path)) == f"{path}:{line}: {message}"


@pytest.mark.parametrize(
    ("keep", "last", "line", "message"),
    [
        (
            7,
            None,
            7,
            f"unexpected end of file: expected candela value 1 of 3 at horizontal angle 0 "
            f"{DEMAND} 18)",
        ),
        (3, "1 1000 1", 4, "unexpected end of file: expected number of vertical angles"),
        (3, None, 3, "unexpected end of file: expected number of lamps"),
    ],
)
def test_truncated_files_are_reported_at_the_last_line(tmp_path, keep, last, line, message):
    lines = BASE.splitlines()[:keep] + ([last] if last else [])
    path = tmp_path / "bad.ies"
    path.write_text("\n".join(lines) + "\n")
    assert error_text(lambda: read_ies(path)) == f"{path}:{line}: {message}"


def test_base_of_the_malformed_cases_is_valid(tmp_path):
    path = tmp_path / "good.ies"
    path.write_text(BASE)
    t = read_ies(path)
    assert t.symmetry == "bilateral_0_180"
    np.testing.assert_array_equal(t.candela, [[100, 50, 10], [100, 40, 5]])


def test_truncation_is_reported_at_the_last_non_blank_line(tmp_path):
    path = tmp_path / "bad.ies"
    path.write_text(replace_line(BASE, 9, None) + "\n\n")
    assert error_text(lambda: read_ies(path)).startswith(f"{path}:8: unexpected end of file")


def test_horizontal_set_error_names_the_first_angle_when_it_is_wrong(tmp_path):
    text = replace_line(BASE, 7, "45")
    text = replace_line(text, 8, "180 100 50 10")  # n_h = 2: 45 (line 7) .. 180 (line 8)
    path = tmp_path / "bad.ies"
    path.write_text(text)
    assert error_text(lambda: read_ies(path)).startswith(f"{path}:7: horizontal angles 45..180:")


def test_empty_and_missing_files(tmp_path):
    empty = tmp_path / "empty.ies"
    empty.write_text("\n \n")
    assert (
        error_text(lambda: read_ies(empty))
        == f"{empty}: the file is empty: expected an IES LM-63 file"
    )
    missing = tmp_path / "missing.ies"
    assert error_text(lambda: read_ies(missing)) == f"{missing}: photometric file not found"


# --------------------------------------------------------------------------- writing


@pytest.mark.parametrize(
    "name",
    [
        "axial_2002.ies",
        "quadrant_1995.ies",
        "bilateral_0_180_2019.ies",
        "bilateral_90_270_1991.ies",
        "none_1986.ies",
        "wrapped_2002.ies",
    ],
)
def test_write_read_round_trip_is_exact(tmp_path, name):
    original = read_ies(DATA / name)
    path = tmp_path / "out.ies"
    write_ies(path, original)
    data = path.read_bytes()
    assert data.startswith(b"IESNA:LM-63-2002\r\n")
    assert b"\r\nTILT=NONE\r\n" in data
    back = read_ies(path)
    assert back.symmetry == original.symmetry
    assert back.lamp_lumens == original.lamp_lumens
    assert back.luminaire == original.luminaire
    assert back.multiplier == 1.0
    np.testing.assert_array_equal(back.vertical_deg, original.vertical_deg)
    np.testing.assert_array_equal(back.horizontal_deg, original.horizontal_deg)
    np.testing.assert_array_equal(back.candela, original.candela)
    assert [p.name for p in tmp_path.iterdir()] == ["out.ies"]


def random_table(rng: np.random.Generator) -> PhotometricTable:
    vertical = np.concatenate([[0.0], np.sort(rng.uniform(0.5, 180.0, size=14))])
    horizontal = np.concatenate([[0.0], np.sort(rng.uniform(0.5, 179.5, size=12)), [180.0]])
    candela = rng.uniform(0.0, 5000.0, size=(14, 15))
    return PhotometricTable(
        vertical_deg=vertical,
        horizontal_deg=horizontal,
        candela=candela,
        source="random",
        symmetry="bilateral_0_180",
        lamp_lumens=float(rng.uniform(100.0, 9000.0)),
        luminaire="random ä",
    )


def test_random_table_round_trip_exact_and_to_printed_digits(tmp_path):
    rng = np.random.default_rng(11)
    table = random_table(rng)
    path = tmp_path / "random.ies"
    write_ies(path, table)
    back = read_ies(path)
    np.testing.assert_array_equal(back.vertical_deg, table.vertical_deg)
    np.testing.assert_array_equal(back.horizontal_deg, table.horizontal_deg)
    np.testing.assert_array_equal(back.candela, table.candela)
    assert back.lamp_lumens == table.lamp_lumens
    assert back.luminaire == "random ä"
    write_ies(path, table, digits=5)
    back = read_ies(path)
    rounded = np.vectorize(lambda v: float(f"{v:.5g}"))
    np.testing.assert_array_equal(back.vertical_deg, rounded(table.vertical_deg))
    np.testing.assert_array_equal(back.candela, rounded(table.candela))


def test_writing_a_table_without_the_360_plane_adds_it(tmp_path):
    table = read_ldt(DATA / "isym0_none.ldt")  # C0 .. C315
    path = tmp_path / "none.ies"
    write_ies(path, table)
    back = read_ies(path)
    np.testing.assert_array_equal(back.horizontal_deg, [0, 45, 90, 135, 180, 225, 270, 315, 360])
    np.testing.assert_array_equal(back.candela[-1], table.candela[0])
    for a, b in zip(expand_full(back), expand_full(table), strict=True):
        np.testing.assert_array_equal(a, b)


def test_keywords_are_written_with_more_lines(tmp_path):
    table = read_ies(DATA / "axial_2002.ies")
    path = tmp_path / "k.ies"
    write_ies(path, table, keywords={"LUMCAT": "A-1", "OTHER": "first\nsecond", "TEST": "T-9"})
    lines = path.read_text().splitlines()
    assert lines[:9] == [
        "IESNA:LM-63-2002",
        "[TEST] T-9",
        "[TESTLAB] unknown",
        "[ISSUEDATE] unknown",
        "[MANUFAC] unknown",
        "[LUMINAIRE] Axial downlight with a frosted lens",
        "[LUMCAT] A-1",
        "[OTHER] first",
        "[MORE] second",
    ]
    assert lines[9:12] == ["TILT=NONE", "1 1000 1 4 1 1 2 0 0 0", "1 1 0"]
    with pytest.raises(InputError) as info:
        write_ies(path, table, keywords={"lum cat": "x"})
    assert str(info.value) == (
        "keywords: keyword 'lum cat': expected upper-case letters, digits and underscores"
    )


def test_write_to_a_missing_folder(tmp_path):
    table = read_ies(DATA / "axial_2002.ies")
    path = tmp_path / "nowhere" / "a.ies"
    assert error_text(lambda: write_ies(path, table)) == (
        f"{path}: cannot write: folder {str(path.parent)!r} does not exist"
    )
