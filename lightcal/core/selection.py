"""Which pixels enter the calibration: masks, regions and selection strategies.

A pixel is a candidate when it is not saturated, its value is above the noise floor,
it lies outside user masks and marker areas, and (when include regions exist) inside
one of them and outside every exclude region. Of the candidates, a strategy picks:

- ``random``: N per image, uniformly, deterministic for a seed (the paper used 100);
- ``grid``: every `grid_step`-th pixel in both directions (offset half a step);
- ``all``: every super-pixel of the image binned b x b whose b^2 pixels are all candidates.

Pixel coordinates follow the project convention (pixel (u, v) centre at integers).
Footprint validity (the pixel sees the wall) is checked afterwards by the renderer;
`select_pixels` over-draws so that N valid pixels usually remain.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

Strategy = Literal["random", "grid", "all"]


@dataclass(frozen=True)
class Region:
    """A rectangle (2 opposite corners) or polygon (>= 3 vertices) in pixel coordinates.

    Attributes:
        kind: "rect" or "polygon".
        points: (K, 2) vertices (u, v).
        include: True to include, False to exclude.
    """

    kind: Literal["rect", "polygon"]
    points: np.ndarray
    include: bool = True

    def contains(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(N,) whether pixel centres (u, v) lie inside (even-odd rule for polygons)."""
        pts = np.asarray(self.points, dtype=np.float64)
        if self.kind == "rect":
            u0, u1 = sorted((pts[0, 0], pts[1, 0]))
            v0, v1 = sorted((pts[0, 1], pts[1, 1]))
            return (u >= u0) & (u <= u1) & (v >= v0) & (v <= v1)
        inside = np.zeros(u.shape, dtype=bool)
        n = pts.shape[0]
        for k in range(n):
            x1, y1 = pts[k]
            x2, y2 = pts[(k + 1) % n]
            crosses = (y1 > v) != (y2 > v)
            with np.errstate(divide="ignore", invalid="ignore"):
                x_at = x1 + (v - y1) * (x2 - x1) / (y2 - y1)
            inside ^= crosses & (u < x_at)
        return inside


@dataclass(frozen=True)
class SelectionOptions:
    """How pixels are selected (see module docstring).

    Attributes:
        strategy: "random", "grid" or "all".
        n_per_image: N for "random".
        grid_step: step for "grid".
        binning: b for "all" (super-pixels); 1 otherwise.
        seed: seed of the random strategy (per image: seed + image index).
        min_signal: values at or below are dropped; None: the caller's noise floor.
    """

    strategy: Strategy = "random"
    n_per_image: int = 100
    grid_step: int = 32
    binning: int = 1
    seed: int = 0
    min_signal: float | None = None

    def __post_init__(self) -> None:
        if self.strategy not in ("random", "grid", "all"):
            raise ValueError(f"strategy: expected random, grid or all, got {self.strategy!r}")
        for name in ("n_per_image", "grid_step", "binning"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {getattr(self, name)}")


def region_mask(regions: list[Region], width: int, height: int) -> np.ndarray:
    """(H, W) bool: pixels allowed by the include/exclude regions (all if none include)."""
    v, u = np.mgrid[0:height, 0:width]
    u = u.ravel().astype(np.float64)
    v = v.ravel().astype(np.float64)
    includes = [r for r in regions if r.include]
    allowed = np.zeros(u.shape, dtype=bool) if includes else np.ones(u.shape, dtype=bool)
    for r in includes:
        allowed |= r.contains(u, v)
    for r in regions:
        if not r.include:
            allowed &= ~r.contains(u, v)
    return allowed.reshape(height, width)


def candidate_mask(
    values: np.ndarray,
    *,
    saturated: np.ndarray | None = None,
    excluded: np.ndarray | None = None,
    regions: list[Region] | None = None,
    min_signal: float = 0.0,
) -> np.ndarray:
    """(H, W) pixels usable for calibration.

    Args:
        values: (H, W) linear pixel values.
        saturated: (H, W) saturated pixels.
        excluded: (H, W) user-mask and marker pixels.
        regions: include/exclude regions.
        min_signal: values at or below are dropped (noise floor).
    """
    h, w = values.shape
    ok = np.isfinite(values) & (values > min_signal)
    if saturated is not None:
        ok &= ~saturated
    if excluded is not None:
        ok &= ~excluded
    if regions:
        ok &= region_mask(regions, w, h)
    return ok


def binned_candidates(candidates: np.ndarray, b: int) -> np.ndarray:
    """(H // b, W // b): super-pixels whose b x b pixels are all candidates."""
    h, w = candidates.shape
    c = candidates[: h // b * b, : w // b * b]
    # Row by row, then along each row: 3x faster on a 6 MP image than NumPy's reduction
    # over the two strided axes of a (H / b, b, W / b, b) view.
    acc = c[0::b].copy()
    for k in range(1, b):
        acc &= c[k::b]
    return np.all(acc.reshape(h // b, w // b, b), axis=2)


def bin_values(values: np.ndarray, b: int) -> np.ndarray:
    """(H // b, W // b) mean of each b x b block (what a binned sensor reads)."""
    h, w = values.shape
    v = values[: h // b * b, : w // b * b]
    # Rows summed first, then along each row (as `binned_candidates`): 1.7x faster than
    # a mean over the strided axes; the same value to a few units of the last bit.
    acc = np.array(v[0::b], dtype=np.float64)
    for k in range(1, b):
        acc += v[k::b]
    return acc.reshape(h // b, w // b, b).sum(axis=2) / (b * b)


def select_pixels(
    candidates: np.ndarray,
    options: SelectionOptions,
    *,
    image_index: int = 0,
    oversample: float = 1.0,
) -> np.ndarray:
    """Pick pixels among candidates.

    Args:
        candidates: (H, W) bool, already binned for strategy "all".
        options: the strategy.
        image_index: added to the seed so images get different random pixels.
        oversample: draw this many times N (random) so invalid footprints can be dropped.

    Returns:
        (N, 2) int64 pixel indices (u, v), sorted by (v, u).
    """
    w = candidates.shape[1]
    if options.strategy == "grid":
        s = options.grid_step
        # Only the grid's rows and columns are looked at.
        sub = candidates[s // 2 :: s, s // 2 :: s]
        vs, us = np.nonzero(sub)
        return np.stack([us * s + s // 2, vs * s + s // 2], axis=1).astype(np.int64)
    # Flat indices: one array where np.nonzero makes two (half the time on a frame).
    flat = np.flatnonzero(candidates)
    if options.strategy == "random":
        rng = np.random.default_rng([options.seed, image_index])
        n = min(flat.size, int(np.ceil(options.n_per_image * oversample)))
        idx = np.sort(rng.choice(flat.size, size=n, replace=False)) if n else np.zeros(0, int)
        flat = flat[idx]
    # (v, u) written straight into the result's columns: a stack and a copy of every
    # pixel's indices fewer (a full frame of 4.8 M pixels: 52 -> 27 ms).
    uv = np.empty((flat.size, 2), dtype=np.int64)
    np.divmod(flat, w, out=(uv[:, 1], uv[:, 0]))
    return uv
