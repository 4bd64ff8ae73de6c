"""Tests of lightcal.io.photometric_table (the table, its unfolding, RIDs and CSV profiles)
and lightcal.io.photometric_file (the reader by suffix)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.core.rid import SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.photometric_file import read_photometric_table, read_rid_file
from lightcal.io.photometric_table import (
    PhotometricTable,
    expand_full,
    read_rid_csv,
    table_to_rid,
    write_rid_csv,
)

DATA = Path(__file__).parent / "data" / "photometry"


def table(horizontal, candela, symmetry, vertical=(0.0, 45.0, 90.0)) -> PhotometricTable:
    return PhotometricTable(
        vertical_deg=np.array(vertical, dtype=float),
        horizontal_deg=np.array(horizontal, dtype=float),
        candela=np.array(candela, dtype=float),
        source="test table",
        symmetry=symmetry,
    )


def f(rid, theta_deg, c_deg=0.0) -> float:
    """The RID at vertical angle gamma = theta and horizontal angle C (phi = -C): the
    table's exact interpolation (the renderer's grid: tests/test_rid_grid.py)."""
    theta, phi = np.array(math.radians(theta_deg)), np.array(math.radians(-c_deg))
    return float(rid.value_and_derivatives(theta, phi, exact=True)[0])


def error_text(call) -> str:
    with pytest.raises(InputError) as info:
        call()
    return str(info.value)


# --------------------------------------------------------------------------- the table


def test_table_arrays_are_float_and_read_only():
    t = table([0], [[4, 2, 1]], "axial")
    assert t.candela.dtype == np.float64
    for array in (t.vertical_deg, t.horizontal_deg, t.candela):
        assert not array.flags.writeable
    with pytest.raises(ValueError):
        t.candela[0, 0] = 1.0


@pytest.mark.parametrize(
    ("horizontal", "candela", "symmetry", "message"),
    [
        (
            [0, 90],
            [[1, 1, 1], [1, 1, 1]],
            "axial",
            "horizontal angles 0..90: expected the single angle 0 for symmetry 'axial'",
        ),
        (
            [0, 180],
            [[1, 1, 1], [1, 1, 1]],
            "quadrant",
            "horizontal angles 0..180: expected 0..90 for symmetry 'quadrant'",
        ),
        (
            [0, 180],
            [[1, 1, 1], [1, 1, 1]],
            "bilateral_90_270",
            "horizontal angles 0..180: expected 90..270 for symmetry 'bilateral_90_270'",
        ),
        (
            [0, 360],
            [[1, 1, 1], [1, 1, 1]],
            "none",
            "horizontal angles 0..360: expected at least 2 planes from 0 up to at most 360 "
            "for symmetry 'none'",
        ),
        (
            [0, 90],
            [[1, 1, 1]],
            "quadrant",
            "candela: expected shape (2, 3) (horizontal x vertical angles), got (1, 3)",
        ),
        (
            [0, 90],
            [[1, 1, 1], [1, -1, 1]],
            "quadrant",
            "candela: expected values >= 0, got a negative value",
        ),
        (
            [0, 90],
            [[1, 1, 1], [1, np.nan, 1]],
            "quadrant",
            "candela: expected finite values, got NaN or inf",
        ),
        (
            [90, 0],
            [[1, 1, 1], [1, 1, 1]],
            "quadrant",
            "horizontal angles: expected strictly increasing values",
        ),
        (
            [0, 90],
            [[1, 1, 1], [1, 1, 1]],
            "round",
            "symmetry 'round': expected one of axial, quadrant, bilateral_0_180, "
            "bilateral_90_270, none",
        ),
    ],
)
def test_table_validation_messages(horizontal, candela, symmetry, message):
    assert error_text(lambda: table(horizontal, candela, symmetry)) == f"test table: {message}"


def test_table_vertical_angle_checks():
    assert error_text(lambda: table([0], [[1]], "axial", vertical=[0])) == (
        "test table: expected at least 2 vertical angles, got 1"
    )
    assert error_text(lambda: table([0], [[1, 1]], "axial", vertical=[0, 190])) == (
        "test table: vertical angles: expected values in [0, 180] degrees, got 0..190"
    )


# --------------------------------------------------------------------------- expand_full


def test_expand_axial_is_the_single_plane():
    phi, cd = expand_full(table([0], [[4, 2, 1]], "axial"))
    np.testing.assert_array_equal(phi, [0.0])
    np.testing.assert_array_equal(cd, [[4, 2, 1]])


def test_expand_quadrant_mirrors_into_four_quadrants():
    rows = [[9, 1, 0], [9, 2, 0], [9, 3, 0]]
    phi, cd = expand_full(table([0, 30, 90], rows, "quadrant"))
    np.testing.assert_array_equal(phi, [0, 30, 90, 150, 180, 210, 270, 330])
    np.testing.assert_array_equal(cd[:, 1], [1, 2, 3, 2, 1, 2, 3, 2])


def test_expand_bilateral_0_180_mirrors_about_the_c0_c180_plane():
    rows = [[9, k, 0] for k in (1, 2, 3, 4)]
    phi, cd = expand_full(table([0, 20, 100, 180], rows, "bilateral_0_180"))
    np.testing.assert_array_equal(phi, [0, 20, 100, 180, 260, 340])
    np.testing.assert_array_equal(cd[:, 1], [1, 2, 3, 4, 3, 2])


def test_expand_bilateral_90_270_mirrors_about_the_c90_c270_plane():
    # I(C) = I(180 - C): 0 <- 180, 60 <- 120, 300 <- 240.
    rows = [[9, k, 0] for k in (1, 2, 3, 4, 5)]
    phi, cd = expand_full(table([90, 120, 180, 240, 270], rows, "bilateral_90_270"))
    np.testing.assert_array_equal(phi, [0, 60, 90, 120, 180, 240, 270, 300])
    np.testing.assert_array_equal(cd[:, 1], [3, 2, 1, 2, 3, 4, 5, 4])


def test_expand_none_drops_the_duplicate_360_plane():
    rows = [[9, 1, 0], [9, 2, 0], [9, 3, 0], [9, 7, 0]]
    phi, cd = expand_full(table([0, 120, 240, 360], rows, "none"))
    np.testing.assert_array_equal(phi, [0, 120, 240])
    np.testing.assert_array_equal(cd[:, 1], [1, 2, 3])
    phi, cd = expand_full(table([0, 120, 240], rows[:3], "none"))
    np.testing.assert_array_equal(phi, [0, 120, 240])
    np.testing.assert_array_equal(cd[:, 1], [1, 2, 3])


# --------------------------------------------------------------------------- table_to_rid


def test_axial_table_gives_a_symmetric_rid():
    rid = table_to_rid(table([0], [[40, 30, 10]], "axial"))
    assert isinstance(rid, SymmetricTableRID)
    assert f(rid, 0) == pytest.approx(1.0)
    assert f(rid, 45, 123) == pytest.approx(0.75)
    assert f(rid, 90) == pytest.approx(0.25)
    assert f(rid, 91) == 0.0  # beyond the table


def test_quadrant_table_gives_a_2d_rid_equal_to_the_table_at_its_angles():
    rid = table_to_rid(table([0, 45, 90], [[20, 10, 2], [20, 12, 4], [20, 14, 6]], "quadrant"))
    assert isinstance(rid, Table2DRID)
    assert f(rid, 0, 77) == pytest.approx(1.0)
    assert f(rid, 45, 45) == pytest.approx(0.6)
    assert f(rid, 45, 135) == pytest.approx(0.6)
    assert f(rid, 45, 180) == pytest.approx(0.5)
    assert f(rid, 90, 270) == pytest.approx(0.3)
    assert f(rid, 90, -45) == pytest.approx(0.2)
    assert f(rid, 120, 45) == 0.0


@pytest.mark.parametrize(
    ("symmetry", "horizontal", "mirror"),
    [
        ("quadrant", [0, 30, 50, 90], lambda p: 180.0 - p),
        ("quadrant", [0, 30, 50, 90], lambda p: -p),
        ("bilateral_0_180", [0, 30, 100, 150, 180], lambda p: -p),
        ("bilateral_90_270", [90, 100, 180, 250, 270], lambda p: 180.0 - p),
    ],
)
def test_rid_keeps_the_mirror_symmetry_between_the_table_angles(symmetry, horizontal, mirror):
    rng = np.random.default_rng(7)
    n_h = len(horizontal)
    candela = rng.uniform(1.0, 5.0, size=(n_h, 4))
    candela[:, 0] = 5.0
    rid = table_to_rid(table(horizontal, candela, symmetry, vertical=[0, 20, 50, 90]))
    theta = rng.uniform(0.0, 90.0, size=50)
    phi = rng.uniform(0.0, 360.0, size=50)
    for t, p in zip(theta, phi, strict=True):
        assert f(rid, t, p) == pytest.approx(f(rid, t, mirror(p)), rel=1e-12, abs=1e-15)


def test_2d_rid_is_normalised_by_the_mean_axis_intensity():
    rid = table_to_rid(table([0, 90], [[10, 5, 1], [10, 8, 2]], "quadrant"))
    assert f(rid, 45, 90) == pytest.approx(0.8)


def test_uplight_table_is_rejected():
    uplight = table([0], [[0, 5, 10]], "axial", vertical=[90, 135, 180])
    assert error_text(lambda: table_to_rid(uplight)) == (
        "test table: vertical angles start at 90 degrees: expected the table to start at "
        "gamma 0 (the light axis); uplight tables (vertical angles 90..180) are not supported"
    )


def test_zero_intensity_on_the_axis_is_rejected():
    dark = table([0, 90], [[0, 5, 10], [0, 5, 10]], "quadrant")
    assert error_text(lambda: table_to_rid(dark)) == (
        "test table: the intensity on the light axis (gamma 0) is 0: expected a positive "
        "value, the RID is normalised to 1 there"
    )


# --------------------------------------------------------------------------- CSV


def write(tmp_path: Path, text: str, name: str = "profile.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_read_csv_with_header_comments_and_blank_lines(tmp_path):
    path = write(
        tmp_path,
        "# measured profile\ntheta_deg, intensity\n\n0, 2.0   # on the axis\n30,1.5\n60, 0.5\n",
    )
    rid = read_rid_csv(path)
    np.testing.assert_allclose(rid.theta_rad, np.deg2rad([0, 30, 60]), rtol=0, atol=0)
    np.testing.assert_array_equal(rid.values, [1.0, 0.75, 0.25])
    assert f(rid, 30) == pytest.approx(0.75)
    assert f(rid, 61) == 0.0


def test_read_csv_without_header_and_blank_separated(tmp_path):
    rid = read_rid_csv(write(tmp_path, "0 4\n90\t1\n"))
    np.testing.assert_array_equal(rid.values, [1.0, 0.25])


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("0,1\n10,abc\n", 2, "cell 'abc': expected a number"),
        ("angle,value\n0,1\nx,y\n", 3, "cell 'x': expected a number"),
        ("0,1\n10,0.5,7\n", 2, "expected 2 columns (angle in degrees, relative intensity), got 3"),
        ("0,1\n10\n", 2, "expected 2 columns (angle in degrees, relative intensity), got 1"),
        (
            "0,1\n20,0.5\n20,0.2\n",
            3,
            "angle 20 is not greater than the previous angle 20: "
            "expected strictly increasing angles",
        ),
        ("0,1\n20,-0.5\n", 2, "relative intensity -0.5 is negative: expected values >= 0"),
        ("5,1\n20,0.5\n", 1, "first angle is 5 degrees: expected 0 (the light axis)"),
        (
            "# only one row\n0,1\n",
            2,
            "expected at least 2 data rows (angle in degrees, relative intensity), got 1",
        ),
        ("0,1\n20,nan\n", 2, "cell 'nan': expected a finite number"),
        ("0,1\n190,0.5\n", 2, "angle 190 degrees: expected angles <= 180"),
        (
            "0,0\n20,0.5\n",
            1,
            "relative intensity on the axis (angle 0) is 0: expected a positive value",
        ),
    ],
)
def test_read_csv_errors_name_file_and_line(tmp_path, text, line, message):
    path = write(tmp_path, text)
    assert error_text(lambda: read_rid_csv(path)) == f"{path}:{line}: {message}"


def test_read_csv_missing_file(tmp_path):
    path = tmp_path / "missing.csv"
    assert error_text(lambda: read_rid_csv(path)) == f"{path}: photometric file not found"


def test_csv_round_trip_is_exact(tmp_path):
    rng = np.random.default_rng(3)
    theta_deg = np.concatenate([[0.0], np.sort(rng.uniform(0.1, 180.0, size=20))])
    values = rng.uniform(0.0, 3.0, size=21)
    values[0] = 2.5
    path = tmp_path / "profile.csv"
    write_rid_csv(path, theta_deg, values)
    assert path.read_text().splitlines()[0] == "theta_deg,relative_intensity"
    rid = read_rid_csv(path)
    np.testing.assert_array_equal(rid.theta_rad, np.deg2rad(theta_deg))
    np.testing.assert_array_equal(rid.values, values / 2.5)
    assert [p.name for p in tmp_path.iterdir()] == ["profile.csv"]  # no temporary file left


def test_csv_round_trip_to_printed_digits(tmp_path):
    path = tmp_path / "profile.csv"
    write_rid_csv(path, [0.0, 33.33333, 90.0], [1.0, 0.123456, 0.0], digits=3)
    assert path.read_text() == "theta_deg,relative_intensity\n0,1\n33.3,0.123\n90,0\n"
    rid = read_rid_csv(path)
    np.testing.assert_array_equal(rid.values, [1.0, 0.123, 0.0])


def test_write_csv_errors(tmp_path):
    path = tmp_path / "p.csv"
    assert error_text(lambda: write_rid_csv(path, [0, 1, 2], [1, 2])) == (
        f"{path}: expected angles and values of the same 1-D shape, got (3,) and (2,)"
    )
    missing = tmp_path / "nowhere" / "p.csv"
    assert error_text(lambda: write_rid_csv(missing, [0, 1], [1, 1])) == (
        f"{missing}: cannot write: folder {str(missing.parent)!r} does not exist"
    )


# --------------------------------------------------------------------------- dispatch


def test_read_rid_file_picks_the_reader_by_suffix(tmp_path):
    assert isinstance(read_rid_file(DATA / "axial_2002.ies"), SymmetricTableRID)
    assert isinstance(read_rid_file(DATA / "isym4_quadrant.ldt"), Table2DRID)
    assert isinstance(read_rid_file(write(tmp_path, "0,1\n10,1\n")), SymmetricTableRID)
    assert read_photometric_table(DATA / "isym1_axial.ldt").symmetry == "axial"
    other = tmp_path / "light.xml"
    assert error_text(lambda: read_rid_file(other)) == (
        f"{other}: unsupported file suffix '.xml': expected .ies, .ldt or .csv"
    )
    assert error_text(lambda: read_photometric_table(other)) == (
        f"{other}: unsupported file suffix '.xml': expected .ies or .ldt"
    )


def test_type_c_angles_run_clockwise_about_the_light_axis():
    """C is counterclockwise seen looking along the axis (+z): C = 90 is phi = 270 (-y)."""
    cd = np.array([[10.0, 8.0], [10.0, 2.0], [10.0, 5.0], [10.0, 6.0]])  # C = 0, 90, 180, 270
    table = PhotometricTable(
        vertical_deg=np.array([0.0, 40.0]),
        horizontal_deg=np.array([0.0, 90.0, 180.0, 270.0]),
        candela=cd,
        source="handedness.ies",
        symmetry="none",
    )
    rid = table_to_rid(table)
    theta = np.full(4, math.radians(40.0))
    phi_light = np.radians([0.0, 270.0, 180.0, 90.0])  # the C-planes 0, 90, 180, 270
    np.testing.assert_allclose(rid(theta, phi_light), [0.8, 0.2, 0.5, 0.6], rtol=1e-12)
    assert isinstance(rid, Table2DRID)
    np.testing.assert_allclose(rid.phi_rad, np.radians([0.0, 90.0, 180.0, 270.0]))
