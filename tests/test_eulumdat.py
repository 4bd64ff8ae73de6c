"""Tests of lightcal.io.eulumdat: EULUMDAT files of every Isym, errors, round trips."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.core.rid import SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.eulumdat import read_ldt, write_ldt
from lightcal.io.ies import read_ies
from lightcal.io.photometric_table import PhotometricTable, expand_full, table_to_rid

DATA = Path(__file__).parent / "data" / "photometry"
EIGHT_PLANES = [0, 45, 90, 135, 180, 225, 270, 315]

# Line numbers in the data files (1 lamp set): C angles 43-50, gamma 51-53, intensities 54-.


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


def test_isym1_axial_converts_cd_per_klm_with_flux_and_factor():
    t = read_ldt(DATA / "isym1_axial.ldt")
    assert t.symmetry == "axial"
    assert t.luminaire == "Axial spot"
    assert t.lamp_lumens == 500.0
    assert t.multiplier == 1.0  # 500 lm / 1000 x conversion factor 2
    np.testing.assert_array_equal(t.vertical_deg, [0, 45, 90])
    np.testing.assert_array_equal(t.horizontal_deg, [0])
    np.testing.assert_array_equal(t.candela, [[400, 300, 100]])
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, [0])
    np.testing.assert_array_equal(cd, [[400, 300, 100]])
    rid = table_to_rid(t)
    assert isinstance(rid, SymmetricTableRID)
    assert f(rid, 45, 200) == pytest.approx(0.75)
    assert f(rid, 90) == pytest.approx(0.25)
    assert f(rid, 100) == 0.0


def test_isym4_quadrant_with_a_decimal_comma_factor():
    t = read_ldt(DATA / "isym4_quadrant.ldt")
    assert t.symmetry == "quadrant"
    assert t.multiplier == 2.0  # 2000 lm / 1000 x 1,0
    np.testing.assert_array_equal(t.horizontal_deg, [0, 45, 90])
    np.testing.assert_array_equal(t.candela, [[100, 50, 10], [100, 60, 20], [100, 70, 30]])
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, EIGHT_PLANES)
    np.testing.assert_array_equal(cd[:, 1], [50, 60, 70, 60, 50, 60, 70, 60])
    rid = table_to_rid(t)
    assert isinstance(rid, Table2DRID)
    assert f(rid, 45, 135) == pytest.approx(0.6)
    assert f(rid, 45, 270) == pytest.approx(0.7)
    assert f(rid, 90, 315) == pytest.approx(0.2)
    assert f(rid, 30, 200) == pytest.approx(f(rid, 30, 340), rel=1e-12)


def test_isym2_bilateral_0_180():
    t = read_ldt(DATA / "isym2_bilateral_0_180.ldt")
    assert t.symmetry == "bilateral_0_180"
    np.testing.assert_array_equal(t.horizontal_deg, [0, 45, 90, 135, 180])
    np.testing.assert_array_equal(
        t.candela, [[100, 80, 60], [100, 70, 50], [100, 60, 40], [100, 50, 30], [100, 40, 20]]
    )
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, EIGHT_PLANES)
    np.testing.assert_array_equal(cd[:, 1], [80, 70, 60, 50, 40, 50, 60, 70])
    rid = table_to_rid(t)
    assert f(rid, 45, 225) == pytest.approx(0.5)
    assert f(rid, 90, 270) == pytest.approx(0.4)
    assert f(rid, 45, 200) == pytest.approx(f(rid, 45, 160), rel=1e-12)
    assert f(rid, 60, 200) == pytest.approx(f(rid, 60, 160), rel=1e-12)


def test_isym3_bilateral_90_270_mirrors_c270_to_c90_onto_90_to_270():
    # Stored in the file, in order: C270 (50 10 1), C315 (50 20 2), C0 (50 30 3),
    # C45 (50 40 4), C90 (50 45 5), cd/klm; 2000 lm -> x 2.
    t = read_ldt(DATA / "isym3_bilateral_90_270.ldt")
    assert t.symmetry == "bilateral_90_270"
    np.testing.assert_array_equal(t.horizontal_deg, [90, 135, 180, 225, 270])
    np.testing.assert_array_equal(
        t.candela, [[100, 90, 10], [100, 80, 8], [100, 60, 6], [100, 40, 4], [100, 20, 2]]
    )
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, EIGHT_PLANES)
    # The stored planes come back at their own angles; the others are their mirrors.
    np.testing.assert_array_equal(cd[:, 1], [60, 80, 90, 80, 60, 40, 20, 40])
    np.testing.assert_array_equal(cd[:, 2], [6, 8, 10, 8, 6, 4, 2, 4])
    rid = table_to_rid(t)
    assert f(rid, 45, 45) == pytest.approx(0.8)
    assert f(rid, 45, 135) == pytest.approx(0.8)
    assert f(rid, 45, 225) == pytest.approx(0.4)
    assert f(rid, 90, 180) == pytest.approx(0.06)
    assert f(rid, 30, 20) == pytest.approx(f(rid, 30, 160), rel=1e-12)


def test_isym0_no_symmetry_absolute_photometry():
    t = read_ldt(DATA / "isym0_none.ldt")
    assert t.symmetry == "none"
    assert t.lamp_lumens is None  # -1 lamps: absolute photometry
    assert t.multiplier == 2.0
    np.testing.assert_array_equal(t.horizontal_deg, EIGHT_PLANES)
    np.testing.assert_array_equal(t.candela[:, 1], [20, 30, 40, 50, 60, 70, 80, 90])
    np.testing.assert_array_equal(t.candela[:, 2], [0, 2, 4, 6, 8, 10, 12, 14])
    phi, cd = expand_full(t)
    np.testing.assert_array_equal(phi, EIGHT_PLANES)
    np.testing.assert_array_equal(cd, t.candela)
    rid = table_to_rid(t)
    assert f(rid, 45, 270) == pytest.approx(0.8)
    assert f(rid, 90, 315) == pytest.approx(0.14)
    assert f(rid, 90, -45) == pytest.approx(0.14)


def test_trailing_blank_lines_are_accepted(tmp_path):
    path = tmp_path / "a.ldt"
    path.write_bytes((DATA / "isym4_quadrant.ldt").read_bytes() + b"\r\n  \r\n")
    np.testing.assert_array_equal(
        read_ldt(path).candela, read_ldt(DATA / "isym4_quadrant.ldt").candela
    )


# --------------------------------------------------------------------------- malformed files


def edited(tmp_path: Path, name: str, changes: dict[int, str | None], extra: str = "") -> Path:
    lines = (DATA / name).read_text().splitlines()
    for number in sorted(changes, reverse=True):
        new = changes[number]
        if new is None:
            del lines[number - 1]
        else:
            lines[number - 1] = new
    path = tmp_path / "bad.ldt"
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


@pytest.mark.parametrize(
    ("name", "changes", "extra", "line", "message"),
    [
        (
            "isym4_quadrant.ldt",
            {62: None},
            "",
            61,
            "unexpected end of file: expected line 62, intensity 3 of 3 in C-plane 90",
        ),
        (
            "isym4_quadrant.ldt",
            {4: "eight"},
            "",
            4,
            "number of C-planes Mc: expected a number, got 'eight'",
        ),
        (
            "isym4_quadrant.ldt",
            {3: "5"},
            "",
            3,
            "symmetry indicator Isym 5: expected 0, 1, 2, 3 or 4",
        ),
        (
            "isym4_quadrant.ldt",
            {4: "6"},
            "",
            4,
            "number of C-planes Mc 6: expected a multiple of 4 for Isym 4",
        ),
        (
            "isym2_bilateral_0_180.ldt",
            {4: "7"},
            "",
            4,
            "number of C-planes Mc 7: expected a multiple of 2 for Isym 2",
        ),
        (
            "isym4_quadrant.ldt",
            {6: "2.5"},
            "",
            6,
            "number of intensities per C-plane Ng 2.5: expected an integer >= 2",
        ),
        (
            "isym4_quadrant.ldt",
            {58: "-30"},
            "",
            58,
            "intensity 2 of 3 in C-plane 45 is negative (-30): expected values >= 0",
        ),
        (
            "isym4_quadrant.ldt",
            {53: "45"},
            "",
            53,
            "gamma angle 3 of 3 (45) is not greater than the previous one (45): "
            "expected strictly increasing angles",
        ),
        (
            "isym4_quadrant.ldt",
            {53: "190"},
            "",
            53,
            "gamma angle 3 of 3 is 190: expected angles in [0, 180] degrees",
        ),
        (
            "isym4_quadrant.ldt",
            {45: "100"},
            "",
            45,
            "C angle 3 of 8 is 100: expected 90, where Isym 4 puts a stored C-plane",
        ),
        (
            "isym3_bilateral_90_270.ldt",
            {49: "260"},
            "",
            49,
            "C angle 7 of 8 is 260: expected 270, where Isym 3 puts a stored C-plane",
        ),
        (
            "isym0_none.ldt",
            {50: "360"},
            "",
            50,
            "C angle 8 of 8 is 360: expected angles in [0, 360) degrees",
        ),
        (
            "isym4_quadrant.ldt",
            {},
            "7\n",
            63,
            "unexpected line after the intensities: Isym 4 with Mc 8 and Ng 3 stores "
            "3 C-planes x 3 intensities, ending at line 62",
        ),
        (
            "isym4_quadrant.ldt",
            {24: "0"},
            "",
            24,
            "conversion factor for luminous intensities 0: expected a value > 0",
        ),
        (
            "isym4_quadrant.ldt",
            {29: "lots"},
            "",
            29,
            "total luminous flux of lamp set 1 (lm): expected a number, got 'lots'",
        ),
        (
            "isym4_quadrant.ldt",
            {60: "1e400"},
            "",
            60,
            "intensity 1 of 3 in C-plane 90: expected a finite number, got '1e400'",
        ),
    ],
)
def test_malformed_files_name_the_line(tmp_path, name, changes, extra, line, message):
    path = edited(tmp_path, name, changes, extra)
    assert error_text(lambda: read_ldt(path)) == f"{path}:{line}: {message}"


def test_truncated_header(tmp_path):
    path = tmp_path / "short.ldt"
    path.write_text("company\n1\n1\n")
    assert error_text(lambda: read_ldt(path)) == (
        f"{path}:3: unexpected end of file: expected line 4, number of C-planes Mc"
    )


def test_empty_file(tmp_path):
    path = tmp_path / "empty.ldt"
    path.write_text("")
    assert (
        error_text(lambda: read_ldt(path))
        == f"{path}: the file is empty: expected an EULUMDAT file"
    )


# --------------------------------------------------------------------------- writing


def assert_same_table(back: PhotometricTable, original: PhotometricTable) -> None:
    assert back.symmetry == original.symmetry
    assert back.lamp_lumens == original.lamp_lumens
    assert back.luminaire == original.luminaire
    np.testing.assert_array_equal(back.vertical_deg, original.vertical_deg)
    np.testing.assert_array_equal(back.horizontal_deg, original.horizontal_deg)
    np.testing.assert_allclose(back.candela, original.candela, rtol=1e-12, atol=0)


@pytest.mark.parametrize(
    ("name", "isym"),
    [
        ("isym0_none.ldt", "0"),
        ("isym1_axial.ldt", "1"),
        ("isym2_bilateral_0_180.ldt", "2"),
        ("isym3_bilateral_90_270.ldt", "3"),
        ("isym4_quadrant.ldt", "4"),
    ],
)
def test_write_read_round_trip(tmp_path, name, isym):
    original = read_ldt(DATA / name)
    path = tmp_path / "out.ldt"
    write_ldt(path, original)
    data = path.read_bytes()
    assert b"\r\n" in data
    lines = data.decode().splitlines()
    assert lines[2] == isym
    assert_same_table(read_ldt(path), original)
    assert [p.name for p in tmp_path.iterdir()] == ["out.ldt"]


@pytest.mark.parametrize(
    ("name", "isym"),
    [
        ("axial_2002.ies", "1"),
        ("quadrant_1995.ies", "4"),
        ("bilateral_0_180_2019.ies", "2"),
        ("bilateral_90_270_1991.ies", "3"),
    ],
)
def test_ies_tables_written_as_eulumdat_read_back_the_same(tmp_path, name, isym):
    original = read_ies(DATA / name)
    path = tmp_path / "from_ies.ldt"
    write_ldt(path, original)
    lines = path.read_text().splitlines()
    assert lines[2] == isym
    assert_same_table(read_ldt(path), original)


def test_axial_table_declares_24_planes(tmp_path):
    path = tmp_path / "axial.ldt"
    write_ldt(path, read_ies(DATA / "axial_2002.ies"), company="ACME")
    lines = path.read_text().splitlines()
    assert lines[:7] == ["ACME", "1", "1", "24", "15", "4", "30"]
    assert lines[25:32] == ["1", "1", "unknown", "1000", "", "", "0"]
    assert len(lines) == 42 + 24 + 4 + 4


def test_no_symmetry_ies_table_drops_the_360_plane(tmp_path):
    original = read_ies(DATA / "none_1986.ies")  # 0 .. 360
    path = tmp_path / "none.ldt"
    write_ldt(path, original)
    back = read_ldt(path)
    assert back.symmetry == "none"
    np.testing.assert_array_equal(back.horizontal_deg, [0, 90, 180, 270])
    for a, b in zip(expand_full(back), expand_full(original), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12)


def bilateral_90_270(horizontal: list[float]) -> PhotometricTable:
    n = len(horizontal)
    return PhotometricTable(
        vertical_deg=np.array([0.0, 60.0]),
        horizontal_deg=np.array(horizontal),
        candela=np.column_stack([np.full(n, 5.0), np.arange(1.0, n + 1.0)]),
        source="t",
        symmetry="bilateral_90_270",
    )


def test_bilateral_90_270_that_does_not_fit_isym3_is_written_with_isym0(tmp_path):
    # Unfolded: 0 70 80 90 100 110 180 270 -> index 3 Mc/4 = 6 holds C180, not C270.
    original = bilateral_90_270([90.0, 100.0, 110.0, 180.0, 270.0])
    path = tmp_path / "odd.ldt"
    write_ldt(path, original)
    assert path.read_text().splitlines()[2] == "0"
    back = read_ldt(path)
    assert back.symmetry == "none"
    assert back.lamp_lumens is None
    phi, cd = expand_full(back)
    np.testing.assert_array_equal(phi, [0, 70, 80, 90, 100, 110, 180, 270])
    np.testing.assert_array_equal(cd[:, 1], [4, 3, 2, 1, 2, 3, 4, 5])
    for a, b in zip(expand_full(back), expand_full(original), strict=True):
        np.testing.assert_array_equal(a, b)


def test_bilateral_90_270_that_fits_no_layout_is_refused(tmp_path):
    # Unfolded: 70 80 90 100 110 270: Mc = 6 and no C0 plane.
    path = tmp_path / "odd.ldt"
    assert error_text(lambda: write_ldt(path, bilateral_90_270([90.0, 100.0, 110.0, 270.0]))) == (
        f"{path}: cannot write this bilateral 90-270 table as EULUMDAT: its unfolded C-planes "
        "(6, from 70) fit neither Isym 3 (C270 and C90 at indices 3 Mc/4 and Mc/4) nor Isym 0 "
        "(a C0 plane first); expected a 180 plane, or as many planes in 90..180 as in 180..270"
    )
    assert not path.exists()


def test_unbalanced_bilateral_90_270_that_fits_isym3(tmp_path):
    # Unfolded: 80 90 100 270 -> Mc = 4, C270 at index 3 and C90 at index 1.
    original = bilateral_90_270([90.0, 100.0, 270.0])
    path = tmp_path / "fits.ldt"
    write_ldt(path, original)
    lines = path.read_text().splitlines()
    assert lines[2:4] == ["3", "4"]
    assert_same_table(read_ldt(path), original)


def test_round_trip_to_printed_digits(tmp_path):
    rng = np.random.default_rng(5)
    candela = rng.uniform(0.0, 1000.0, size=(3, 5))
    original = PhotometricTable(
        vertical_deg=np.array([0.0, 22.5, 45.0, 67.5, 90.0]),
        horizontal_deg=np.array([0.0, 45.0, 90.0]),
        candela=candela,
        source="t",
        symmetry="quadrant",
    )
    path = tmp_path / "digits.ldt"
    write_ldt(path, original, digits=4)
    back = read_ldt(path)
    rounded = np.vectorize(lambda v: float(f"{v:.4g}"))
    np.testing.assert_array_equal(back.candela, rounded(candela))  # absolute: 1000 lm, cd = cd/klm
