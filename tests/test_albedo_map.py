"""The wall's albedo map (`lightcal.core.albedo_map`): its basis, the variable projection
against the joint least squares it stands for, and its exact gradient."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from lightcal.core.albedo_map import AlbedoGrid, AlbedoMapOptions, AlbedoProjection
from lightcal.core.qr_factors import economic_r, stack_r_factors


def test_the_bilinear_basis_reproduces_planes_and_is_zero_off_the_grid() -> None:
    grid = AlbedoGrid(np.array([-0.3, 0.2]), 0.05, (7, 9))
    rng = np.random.default_rng(0)
    inside = grid.origin_xy_m + rng.uniform(0.0, 1.0, (200, 2)) * [0.4, 0.3]
    B = grid.basis(inside)
    assert B.shape == (200, 63)
    np.testing.assert_allclose(np.asarray(B.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    plane = lambda p: 0.3 + 2.0 * p[:, 0] - 1.5 * p[:, 1]  # noqa: E731
    np.testing.assert_allclose(B @ plane(grid.node_xy()), plane(inside), atol=1e-12)
    off = np.array([[-0.31, 0.3], [0.0, 0.51], [np.nan, 0.3]])
    assert grid.basis(off).nnz == 0 or np.all(grid.basis(off).toarray() == 0.0)


def test_the_grid_covers_the_points_and_refuses_too_many_nodes() -> None:
    pts = np.array([[0.0, 0.0], [1.0, 0.5]])
    grid = AlbedoGrid.covering(pts, 0.1)
    assert grid.shape == (8, 13)
    assert np.all(np.asarray(grid.basis(pts).sum(axis=1)).ravel() == pytest.approx(1.0))
    with pytest.raises(ValueError) as info:
        AlbedoGrid.covering(np.array([[0.0, 0.0], [10.0, 10.0]]), 0.01)
    assert str(info.value) == (
        "albedo map: 1003 x 1003 nodes at 10 mm cover the 10.02 x 10.02 m the pixels see; "
        "expected at most 250000 (a larger spacing_mm)"
    )


def _problem(seed: int, n: int = 4, offset_column: int = 2):
    """Three images' random systems [J r], their u and bases on one grid."""
    rng = np.random.default_rng(seed)
    grid = AlbedoGrid(np.zeros(2), 0.1, (5, 6))
    systems, scaled, bases = [], [], []
    for rows in (40, 55, 30):
        pts = rng.uniform(0.0, [0.5, 0.4], (rows, 2))
        bases.append(grid.basis(pts))
        systems.append(np.asfortranarray(rng.normal(size=(rows, n + 1))))
        scaled.append(rng.uniform(5.0, 50.0, rows))
    options = AlbedoMapOptions(spacing_m=0.1, variation=0.3, smoothness=0.05)
    return AlbedoProjection(grid, bases, options), systems, scaled, offset_column


@pytest.mark.parametrize("veiled", [False, True], ids=["wall", "wall and veil"])
def test_the_projection_is_the_joint_least_squares_minimised_over_the_albedo(
    veiled: bool,
) -> None:
    """Also with a veil (the water's backscatter) in the systems, which a does not scale:
    the joint model is then a (wall) + veil, its Jacobian a (J - J_veil) + J_veil."""
    projection, systems, scaled, off = _problem(1)
    n = systems[0].shape[1] - 1
    originals = [A.copy() for A in systems]
    rng = np.random.default_rng(7)
    veils = [rng.normal(size=A.shape) if veiled else np.zeros(A.shape) for A in systems]
    albedo, factors, prior = projection.project(systems, scaled, off, veils if veiled else None)
    # delta* minimises sum |r0 - u B delta|^2 + |Gamma delta|^2 (a dense solve).
    Bu = sp.vstack([sp.diags(u) @ B for u, B in zip(scaled, projection.bases, strict=True)])
    design = np.vstack([Bu.toarray(), -projection.gamma.toarray()])
    target = np.concatenate(
        [np.concatenate([A[:, n] for A in originals]), np.zeros(prior.shape[0])]
    )
    delta, *_ = np.linalg.lstsq(design, target, rcond=None)
    np.testing.assert_allclose(albedo.delta, delta, atol=1e-10)
    # The residual column holds r0 - u B delta*, the prior's Gamma delta*: the joint minimum.
    cost = sum(float(A[:, n] @ A[:, n]) for A in systems) + float(prior[:, n] @ prior[:, n])
    assert cost == pytest.approx(float(np.sum((target - design @ delta) ** 2)), rel=1e-10)
    # Every column but the offset's is scaled by a = 1 + B delta*, but for the veil's part.
    for B, a in zip(projection.bases, factors, strict=True):
        np.testing.assert_allclose(a, 1.0 + B @ delta, atol=1e-12)
    # The projected Gauss-Newton matrix is the joint one's Schur complement over delta.
    J1 = np.vstack(
        [
            np.where(np.arange(n) == off, A[:, :n], a[:, None] * (A - V)[:, :n] + V[:, :n])
            for A, V, a in zip(originals, veils, factors, strict=True)
        ]
    )
    M = design.T @ design
    C = Bu.toarray().T @ J1
    schur = J1.T @ J1 - C.T @ np.linalg.solve(M, C)
    R = stack_r_factors(
        [economic_r(A.copy(order="F")) for A in systems] + [economic_r(prior)], n + 1
    )
    np.testing.assert_allclose(R[:n, :n].T @ R[:n, :n], schur, rtol=1e-9, atol=1e-9)


def test_the_projection_leaves_nothing_to_gain_from_the_albedo() -> None:
    """The projected residuals are orthogonal to every albedo direction (the normal
    equations in delta hold at delta*)."""
    projection, systems, scaled, off = _problem(2)
    n = systems[0].shape[1] - 1
    _, _, prior = projection.project(systems, scaled, off)
    Bu = [sp.diags(u) @ B for u, B in zip(scaled, projection.bases, strict=True)]
    normal = sum(b.T @ A[:, n] for b, A in zip(Bu, systems, strict=True))
    normal -= projection.gamma.T @ prior[:, n]
    assert np.abs(normal).max() < 1e-9 * max(
        1.0, np.abs(sum(b.T @ A[:, n] for b, A in zip(Bu, systems, strict=True))).max()
    )


def test_albedo_map_options_are_checked() -> None:
    with pytest.raises(ValueError) as info:
        AlbedoMapOptions(spacing_m=0.0)
    assert str(info.value) == "albedo map: spacing_m: expected a value in (0, 1], got 0.0"
    with pytest.raises(ValueError) as info:
        AlbedoMapOptions(smoothness=float("nan"))
    assert str(info.value) == "albedo map: smoothness: expected a value in (0, 10], got nan"
