"""A NumPy model of how Cycles (Blender 5.0) reads and looks up IES data, as its source
describes it (`intern/cycles/util/ies.cpp`, `intern/cycles/kernel/svm/ies.h`; written here
from that description, not copied):

- The candela values are multiplied by the file's multipliers and by 4 pi / 177.83.
- Type C angles: a single horizontal angle 0 becomes the planes 0 and 360; a table up to
  180 (or 90) is mirrored to 360; the angles are kept in single precision.
- The lookup of a direction at vertical angle v and horizontal angle h: zero outside
  [v_first, v_last) x [h_first, h_last); otherwise the interval holding each angle, and a
  uniform Catmull-Rom spline over the indices (the spacing is ignored) first along v in
  the four neighbouring planes, then along h. The neighbour before the first vertical
  angle is the second one of the same plane (a reflection across the pole), after the
  last one zero (or the one before last when the table ends at 180); horizontally the
  table wraps around when it spans 0..360. Negative results become zero.

Used by tests/test_export_blender.py to check that the exported table, as Cycles
interpolates it, is lightcal's RID.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

WATTS_PER_CANDELA = 0.0706650768394


def _catmull_rom(a, b, c, d, x):
    return (
        0.5 * (((d + 3.0 * (b - c) - a) * x + (2.0 * a - 5.0 * b + 4.0 * c - d)) * x + (c - a)) * x
        + b
    )


def cycles_tables(ies_text: str) -> tuple[NDArray, NDArray, NDArray]:
    """(v_rad, h_rad, intensity (n_h, n_v)) as Cycles keeps the type C table of an IES text."""
    after_tilt = ies_text.replace(",", " ").split("TILT=", 1)[1].split("\n", 1)[1]
    numbers = [float(x) for x in after_tilt.split()]
    factor = numbers[2] * numbers[10] * numbers[11] * WATTS_PER_CANDELA
    n_v, n_h = int(numbers[3]), int(numbers[4])
    assert int(numbers[5]) == 1, "type C only"
    values = numbers[13:]
    v_deg = [float(np.float32(x)) for x in values[:n_v]]
    h = [float(np.float32(x)) for x in values[n_v : n_v + n_h]]
    data = np.array(values[n_v + n_h : n_v + n_h + n_v * n_h]).reshape(n_h, n_v) * factor
    rows = [np.float32(r).astype(np.float64) for r in data]
    if len(h) == 1:
        h, rows = [*h, 360.0], [*rows, rows[0]]
    if h[-1] == 90.0:
        for i in range(len(h) - 2, -1, -1):
            h.append(180.0 - h[i])
            rows.append(rows[i])
    if h[-1] == 180.0:
        for i in range(len(h) - 2, -1, -1):
            h.append(360.0 - h[i])
            rows.append(rows[i])
    if h[-1] != 360.0 and 360.0 - h[-1] in (h[-1] - h[-2], h[1] - h[0]):
        h, rows = [*h, 360.0], [*rows, rows[0]]
    assert h[0] == 0.0 and h[-1] == 360.0 and v_deg[0] == 0.0, (h, v_deg)
    to_rad = np.float32(math.pi) / np.float32(180.0)
    v_rad = (np.asarray(v_deg, dtype=np.float32) * to_rad).astype(np.float64)
    h_rad = (np.asarray(h, dtype=np.float32) * to_rad).astype(np.float64)
    return v_rad, h_rad, np.array(rows)


def cycles_lookup(ies_text: str, v_angle: NDArray, h_angle: NDArray) -> NDArray[np.float64]:
    """The IES node's output (strength 1) for the IES text `ies_text` at vertical angles
    `v_angle` and horizontal angles `h_angle` (radians, same shape), in Cycles' angles."""
    v_tab, h_tab, I = cycles_tables(ies_text)
    v = np.asarray(v_angle, dtype=np.float64).ravel()
    h = np.asarray(h_angle, dtype=np.float64).ravel()
    n_v, n_h = v_tab.size, h_tab.size
    inside = (v >= v_tab[0]) & (v < v_tab[-1]) & (h >= h_tab[0]) & (h < h_tab[-1])
    wrap_h = h_tab[0] < 1e-7 and h_tab[-1] > 2 * math.pi - 1e-7
    wrap_vlow = v_tab[0] < 1e-7
    wrap_vhigh = v_tab[-1] > math.pi - 1e-7
    vi = np.clip(np.searchsorted(v_tab, v, side="left") - 1, 0, n_v - 2)
    hi = np.clip(np.searchsorted(h_tab, h, side="left") - 1, 0, n_h - 2)
    v_frac = (v - v_tab[vi]) / (v_tab[vi + 1] - v_tab[vi])
    h_frac = (h - h_tab[hi]) / (h_tab[hi + 1] - h_tab[hi])

    def column(plane):
        a = np.where(vi > 0, I[plane, np.maximum(vi - 1, 0)], I[plane, 1] if wrap_vlow else 0.0)
        b = I[plane, vi]
        c = I[plane, vi + 1]
        after = np.minimum(vi + 2, n_v - 1)
        d = np.where(vi + 2 < n_v, I[plane, after], I[plane, n_v - 2] if wrap_vhigh else 0.0)
        return _catmull_rom(a, b, c, d, v_frac)

    zero = np.zeros_like(v)
    a = np.where(hi > 0, column(np.maximum(hi - 1, 0)), column(np.full_like(hi, n_h - 2)))
    if not wrap_h:
        a = np.where(hi > 0, a, zero)
    b = column(hi)
    c = column(hi + 1)
    d = np.where(hi + 2 < n_h, column(np.minimum(hi + 2, n_h - 1)), column(np.ones_like(hi)))
    if not wrap_h:
        d = np.where(hi + 2 < n_h, d, zero)
    out = np.maximum(_catmull_rom(a, b, c, d, h_frac), 0.0)
    return np.where(inside, out, 0.0).reshape(np.shape(v_angle))
