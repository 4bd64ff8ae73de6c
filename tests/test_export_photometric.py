"""IES / EULUMDAT exports read by independent parsers (the formats' own layouts, not
lightcal's readers): angles without float noise, a header that says where the RID comes
from, and the EULUMDAT light output ratio and downward flux fraction of the table.

EULUMDAT's layout (one field a line): 1 company, 2 Ityp, 3 Isym, 4 Mc, 5 Dc, 6 Ng, 7 Dg,
8 report number, 9 luminaire name, ..., 22 DFF (downward flux fraction, %), 23 LORL
(light output ratio, %), 24 conversion factor, 25 tilt, 26 number of lamp sets, 26a-f
the set, 27 ten direct ratios, then the C angles, the gamma angles and cd/klm.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.eulumdat import flux_fractions, write_ldt
from lightcal.io.photometric_table import PhotometricTable
from lightcal.io.project import load_project
from lightcal.resources import sample_project_dir
from tests.export_render import result_of_project


def _ies_numbers(text: str) -> tuple[dict[str, str], list[str]]:
    """Keywords and the tokens after TILT=NONE (LM-63-2002)."""
    head, _, body = text.partition("TILT=NONE")
    keywords = dict(re.findall(r"^\[(\w+)\] ?(.*?)\r?$", head, flags=re.M))
    return keywords, body.replace(",", " ").split()


def _ies_angles(text: str) -> tuple[list[str], list[str]]:
    """(vertical, horizontal) angle tokens as written."""
    _, tokens = _ies_numbers(text)
    n_v, n_h = int(tokens[3]), int(tokens[4])
    start = 13  # 10 numbers of line 10, 3 of line 11
    return tokens[start : start + n_v], tokens[start + n_v : start + n_v + n_h]


def _ldt_lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


@pytest.fixture(scope="module")
def sample_exports(tmp_path_factory) -> dict[str, Path]:
    """The sample's light (its profile given by light.ies) exported as IES and LDT."""
    folder = tmp_path_factory.mktemp("photometric")
    project_path = sample_project_dir() / "project.json"
    result = result_of_project(load_project(project_path), [9900.0], folder / "result.json")
    out = {}
    for fmt in ("ies", "ldt"):
        out[fmt] = folder / f"light.{fmt}"
        args = ["export", str(result), "--format", fmt, "--out", str(out[fmt])]
        assert main([*args, "--project", str(project_path)]) == 0
    return out


def test_ies_angles_are_the_profiles_own(sample_exports):
    source = (sample_project_dir() / "light.ies").read_text()
    written = sample_exports["ies"].read_text()
    vertical, horizontal = _ies_angles(written)
    source_vertical, _ = _ies_angles(source)
    assert [float(v) for v in vertical] == [float(v) for v in source_vertical]
    assert all(re.fullmatch(r"-?\d+(\.\d{1,9})?", v) for v in vertical + horizontal), vertical
    assert "3.0000000000000004" not in written


def test_headers_say_the_rid_was_given(sample_exports):
    keywords, _ = _ies_numbers(sample_exports["ies"].read_text())
    assert "given RID" in keywords["TEST"] and "estimated" not in keywords["TEST"]
    lines = _ldt_lines(sample_exports["ldt"])
    assert "given RID" in lines[7] and "estimated" not in "\n".join(lines[:12])


def test_ldt_light_output_ratio_and_downward_fraction(sample_exports):
    lines = _ldt_lines(sample_exports["ldt"])
    dff, lorl = float(lines[21]), float(lines[22])
    assert dff == 100.0  # the table ends at 90 degrees: all flux goes down
    assert lorl == 100.0  # absolute photometry: the luminaire's own flux
    n_c, n_g = int(lines[3]), int(lines[5])
    start = 26 + 6 + 10  # 26 lines, one lamp set of 6, 10 direct ratios
    angles = lines[start : start + n_c + n_g]
    assert all(re.fullmatch(r"-?\d+(\.\d{1,9})?", a) for a in angles), angles


def test_ldt_fractions_of_a_table_with_upward_light(tmp_path):
    """An isotropic 1 cd source over the whole sphere emits 4 pi lm, half downward; rated
    lamps of 8 pi lm give a light output ratio of 50 %."""
    gamma = np.arange(0.0, 181.0, 5.0)
    table = PhotometricTable(
        gamma,
        np.zeros(1),
        np.ones((1, gamma.size)),
        source="t",
        symmetry="axial",
        lamp_lumens=8 * math.pi,
    )
    flux, down = flux_fractions(table)
    assert flux == pytest.approx(4 * math.pi, rel=1e-3)  # trapezoids of sin(gamma)
    assert down == pytest.approx(0.5, abs=1e-12)
    write_ldt(tmp_path / "iso.ldt", table)
    lines = _ldt_lines(tmp_path / "iso.ldt")
    assert float(lines[21]) == pytest.approx(50.0, abs=1e-6)
    assert float(lines[22]) == pytest.approx(50.0, rel=1e-3)


def test_fractions_of_a_table_without_symmetry():
    """Two half-circles of planes: 2 cd on C 0..180 and 0 elsewhere, all downward."""
    gamma = np.arange(0.0, 91.0, 10.0)
    c = np.arange(0.0, 360.0, 30.0)
    candela = np.where((c >= 0) & (c <= 180), 2.0, 0.0)[:, None] * np.ones(gamma.size)
    table = PhotometricTable(gamma, c, candela, source="t", symmetry="none")
    flux, down = flux_fractions(table)
    # each plane weighs half the gaps to its neighbours: 30 deg; 7 lit planes (0..180)
    weight = math.radians(30.0) * 7
    expected = 2.0 * weight * float(np.trapezoid(np.sin(np.radians(gamma)), np.radians(gamma)))
    assert flux == pytest.approx(expected, rel=1e-12)
    assert down == 1.0
