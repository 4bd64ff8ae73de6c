"""Robust plane fit to 3-D points: RANSAC on 3-point samples, then least squares.

The plane is `n . x + d = 0` with `n` a unit normal; the signed distance of a
point x to it is `n . x + d`. Units are those of the points (the fit does not
care whether they are metres or an SfM model's arbitrary units).

1. RANSAC: hypotheses from 3 random points (drawn from the caller's
   `numpy.random.Generator`, in batches), scored by their number of inliers
   (`|distance| <= threshold`), ties broken by the smaller sum of squared inlier
   distances. The number of iterations adapts to the best inlier ratio w seen so
   far: it stops after `log(1 - confidence) / log(1 - w^3)` hypotheses, or
   `max_iters`.
2. Refinement: total least squares (SVD of the centred inliers: the normal is the
   singular vector of the smallest singular value), then the inliers are
   recomputed with the refined plane; repeated until the inlier set is stable.
   Inliers whose RMS spread across their principal line is not more than the
   threshold do not determine a plane: that is an error, not a guess.

Sign of the normal: the fit alone cannot orient the plane, so the normal returned
has its largest-magnitude component positive (a deterministic choice). Callers
that know a side (cameras in front of a wall) flip it themselves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.errors import InputError

_BATCH = 64
"""Hypotheses scored per vectorised batch (at most)."""

_MAX_BATCH_ENTRIES = 4_000_000
"""Cap on hypotheses x points per batch, to bound memory for large point clouds."""

_MAX_REFINE_ROUNDS = 20
"""At most this many (least squares -> inliers) rounds in the refinement."""

DEGENERATE_SIN_TOL = 1e-9
"""A 3-point sample whose triangle has |sin(angle)| below this is collinear (no hypothesis)."""


@dataclass(frozen=True, eq=False)
class PlaneFit:
    """A plane `normal . x + offset = 0` fitted to points.

    Attributes:
        normal: (3,) unit normal, largest-magnitude component positive.
        offset: d in `normal . x + d = 0`, in the points' units.
        inliers: (N,) bool, the points within the threshold of the refined plane.
        rms: Root mean square distance of the inliers to the plane, in the points' units.
    """

    normal: NDArray[np.float64]
    offset: float
    inliers: NDArray[np.bool_]
    rms: float

    @property
    def n_inliers(self) -> int:
        """Number of inliers."""
        return int(np.count_nonzero(self.inliers))

    def signed_distances(self, points: ArrayLike) -> NDArray[np.float64]:
        """Signed distances `normal . x + offset` of points to the plane.

        Args:
            points: (M, 3) points, in the fit's units.

        Returns:
            distances: (M,) positive on the side the normal points to.
        """
        array = _check_points(points, name="points")
        return array @ self.normal + self.offset


def _check_points(points: ArrayLike, *, name: str) -> NDArray[np.float64]:
    """Return `points` as a finite float64 (N, 3) array or raise InputError."""
    try:
        array = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(name, "expected a numeric (N, 3) array") from exc
    if array.ndim != 2 or array.shape[1] != 3:
        raise InputError(name, f"expected an (N, 3) array, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        n_bad = int(np.count_nonzero(~np.all(np.isfinite(array), axis=1)))
        raise InputError(name, f"expected finite coordinates, got {n_bad} rows with NaN or inf")
    return array


def _canonical_normal(normal: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit normal with its largest-magnitude component made positive."""
    unit = normal / np.linalg.norm(normal)
    return -unit if unit[int(np.argmax(np.abs(unit)))] < 0.0 else unit


def _total_least_squares(
    points: NDArray[np.float64],
) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
    """Best plane through points in the least squares sense.

    Args:
        points: (M, 3), M >= 3.

    Returns:
        normal: (3,) unit normal (canonical sign).
        offset: d with `normal . x + d = 0`.
        singular_values: (3,) of the centred points, descending.
    """
    centroid = points.mean(axis=0)
    _, singular_values, vt = np.linalg.svd(points - centroid, full_matrices=False)
    normal = _canonical_normal(vt[-1])
    return normal, float(-normal @ centroid), singular_values


def _adaptive_iterations(inlier_ratio: float, confidence: float, max_iters: int) -> int:
    """Number of 3-point hypotheses needed to draw one all-inlier sample."""
    p_good = inlier_ratio**3
    if p_good >= 1.0:
        return 1
    if p_good <= 0.0:
        return max_iters
    needed = math.log(1.0 - confidence) / math.log(1.0 - p_good)
    return int(min(max_iters, math.ceil(needed)))


def _refit(
    points: NDArray[np.float64], inliers: NDArray[np.bool_], threshold: float
) -> tuple[NDArray[np.float64], float]:
    """Least squares plane through the inliers, or InputError if they do not span a plane.

    The inliers span a plane when their RMS spread along the second principal axis
    exceeds `threshold`: a band narrower than the inlier tolerance is a line, and any
    plane through it would fit.
    """
    selected = points[inliers]
    normal, offset, singular_values = _total_least_squares(selected)
    spread = float(singular_values[1]) / math.sqrt(selected.shape[0])
    if spread <= threshold:
        raise InputError(
            "points",
            f"degenerate plane: the {selected.shape[0]} inliers lie along a line (RMS spread "
            f"{spread:.3g} across it, not more than the threshold {threshold:g}), expected "
            "points spanning a plane",
        )
    return normal, offset


def fit_plane_ransac(
    points: ArrayLike,
    *,
    threshold: float,
    rng: np.random.Generator,
    max_iters: int = 1000,
    confidence: float = 0.999,
) -> PlaneFit:
    """Fit a plane to points with outliers: RANSAC, then least squares on the inliers.

    Args:
        points: (N, 3) points, N >= 3, any consistent unit.
        threshold: Largest distance of an inlier to the plane, in the points' unit, > 0.
        rng: Source of the random samples.
        max_iters: Upper bound on the number of RANSAC hypotheses, >= 1.
        confidence: Probability, in (0, 1), of having drawn at least one all-inlier
            sample when the adaptive stopping rule ends the search.

    Returns:
        The refined plane, its inliers and their RMS distance.

    Raises:
        InputError: Bad arguments; fewer than 3 points; all points collinear or
            coincident; the inliers of the best plane lie along a line (their RMS spread
            across it is not more than `threshold`), so the plane is not determined.
    """
    array = _check_points(points, name="points")
    n_points = array.shape[0]
    if n_points < 3:
        raise InputError("points", f"expected at least 3 points to fit a plane, got {n_points}")
    if not (math.isfinite(threshold) and threshold > 0.0):
        raise InputError("threshold", f"expected a finite distance > 0, got {threshold!r}")
    if isinstance(max_iters, bool) or not isinstance(max_iters, int) or max_iters < 1:
        raise InputError("max_iters", f"expected an int >= 1, got {max_iters!r}")
    if not (0.0 < confidence < 1.0):
        raise InputError("confidence", f"expected a probability in (0, 1), got {confidence!r}")

    best_count = 0
    best_cost = math.inf
    best_normal = np.zeros(3)
    best_offset = 0.0
    iterations_needed = max_iters
    done = 0
    while done < min(max_iters, iterations_needed):
        batch = min(max(1, _MAX_BATCH_ENTRIES // n_points), _BATCH, max_iters - done)
        done += batch
        samples = array[rng.integers(0, n_points, size=(batch, 3))]  # (B, 3, 3)
        edge_a = samples[:, 1] - samples[:, 0]
        edge_b = samples[:, 2] - samples[:, 0]
        normals = np.cross(edge_a, edge_b)
        lengths = np.linalg.norm(normals, axis=1)
        scale = np.linalg.norm(edge_a, axis=1) * np.linalg.norm(edge_b, axis=1)
        ok = lengths > DEGENERATE_SIN_TOL * scale
        if not np.any(ok):
            continue
        normals = normals[ok] / lengths[ok, None]
        offsets = -np.einsum("bi,bi->b", normals, samples[ok, 0])
        distances = np.abs(normals @ array.T + offsets[:, None])  # (B', N)
        inside = distances <= threshold
        counts = np.count_nonzero(inside, axis=1)
        costs = np.where(inside, distances**2, 0.0).sum(axis=1)
        order = np.lexsort((costs, -counts))
        k = int(order[0])
        if counts[k] > best_count or (counts[k] == best_count and costs[k] < best_cost):
            best_count = int(counts[k])
            best_cost = float(costs[k])
            best_normal = normals[k]
            best_offset = float(offsets[k])
            iterations_needed = _adaptive_iterations(best_count / n_points, confidence, max_iters)

    if best_count < 3:
        raise InputError(
            "points",
            "degenerate plane: expected points spanning a plane, but every RANSAC sample "
            f"of {n_points} points was collinear or had fewer than 3 inliers",
        )

    inliers = np.abs(array @ best_normal + best_offset) <= threshold
    normal, offset = _refit(array, inliers, threshold)
    for _ in range(_MAX_REFINE_ROUNDS):
        refit = np.abs(array @ normal + offset) <= threshold
        if np.count_nonzero(refit) < 3 or np.array_equal(refit, inliers):
            break
        inliers = refit
        normal, offset = _refit(array, inliers, threshold)
    distances = array[inliers] @ normal + offset
    rms = float(np.sqrt(np.mean(distances**2)))
    inliers.flags.writeable = False
    normal.flags.writeable = False
    return PlaneFit(normal=normal, offset=offset, inliers=inliers, rms=rms)
