"""What the checks after a solve need of every pixel, from one pass over the images.

`pixel_evidence` evaluates the model at the solution once (`CalibrationModel.evaluate_visiting`)
and keeps, per pixel, the residual in noise units, the signal, the mirror and incidence
angles; per image, its Gram blocks (the jackknife, the `images` cause), a seeded subset of
rows for the camera-pose and intrinsics sensitivities (`POSE_ROWS`) and another, with the
patterns' inputs, for the candidate causes of a misfit (`CAUSE_ROWS`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lightcal.core.misfit_causes import PixelFeatures
from lightcal.core.misfit_kernels import add_weighted_gram, mirror_incidence, noise_residuals
from lightcal.core.port_bend import port_bend_pattern
from lightcal.core.rotations import in_normal_frames
from lightcal.core.scene import Light
from lightcal.core.solver import CalibrationModel
from lightcal.pipeline.measurements import Measurements

#: subset; the sums it enters are scaled to the image's pixel count).
POSE_ROWS = 3000


@dataclass(frozen=True)
class ImageRows:
    """One image's seeded subset of rows (at most `POSE_ROWS`), where the camera-pose and
    intrinsics sensitivities are computed.

    Attributes:
        image: the image's index in the model.
        rows: (k,) sorted row indices into the image's pixels.
        J: (k, n) those rows of the weighted Jacobian d r / d x at the solution.
        noise_ratio: (k,) their solver sigma / noise sigma.
        row_scale: N_i / k (sums over the subset are scaled by it).
    """

    image: int
    rows: np.ndarray
    J: np.ndarray
    noise_ratio: np.ndarray
    row_scale: float


@dataclass(frozen=True)
class PixelEvidence:
    """Per selected pixel of every image, at the solution (model image order, concatenated),
    and what the uncertainty needs of every pixel, all from one pass over the images.

    Attributes:
        r_noise: (m,) residuals in noise units (solver units when the noise is unknown).
        relative: (m,) float32 (m_obs - m_render) / m_render.
        mirror_deg, incidence_deg: (m,) float32 angles of the brightest light at each
            pixel, degrees.
        subsets: per image, the rows of the pose and intrinsics sensitivities.
        noise_middle: (n, n) sum_i J_i^T W_i J_i with W_i = 1 / noise_ratio^2 (the
            noise covariance's sandwich when the solver's weights are not the noise),
            or None when not asked for.
        light_shares: (L,) each light's share of the rendered values, summed over the
            pixels (`dark_light_warnings`).
        image_grams: per image, (J_i^T J_i (n, n), J_i^T r_i (n,), J_i^T diag(sigma^2)
            J_i (n, n)) over all its pixels (solver units): the jackknife and the
            `images` cause.
        signal: (m,) float32 m_render - offset (every light).
        signal2: sum over every pixel of (m_render - offset)^2.
        residual2: sum over every pixel of (m_obs - m_render)^2 (value units).
        rss: sum over every pixel of r^2, the solver's weighted residuals.
        tested: the rows the other causes are tested on (`TestedRows`).
    """

    r_noise: np.ndarray
    relative: np.ndarray
    mirror_deg: np.ndarray
    incidence_deg: np.ndarray
    subsets: list[ImageRows]
    noise_middle: np.ndarray | None
    light_shares: np.ndarray
    image_grams: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
    signal: np.ndarray
    signal2: float
    residual2: float
    rss: float
    tested: TestedRows


#: Most pixels per image the candidate causes of a misfit are tested on (a seeded subset).
CAUSE_ROWS = 4000


@dataclass(frozen=True)
class TestedRows:
    """The rows the candidate causes are tested on (`lightcal.core.alternatives`), every
    image's seeded subset of at most `CAUSE_ROWS` concatenated.

    Attributes:
        J: (k, n) the weighted Jacobian's rows, solver units.
        r: (k,) the weighted residuals.
        sigma: (k,) the solver's sigmas (value units per solver unit).
        features: what the causes' patterns need of these pixels.
    """

    J: np.ndarray
    r: np.ndarray
    sigma: np.ndarray
    features: PixelFeatures


def pixel_evidence(
    model: CalibrationModel,
    x: np.ndarray,
    meas: Measurements,
    *,
    noise_middle: bool = False,
    seed: int = 0,
) -> PixelEvidence:
    """The residuals and angles `check_fit` tests and the rows the sensitivities use (see
    `PixelEvidence`), in one evaluation at x (`CalibrationModel.evaluate_visiting`): the
    residuals, J^T J, each pixel's Jacobian row and each light's flux are rendered once.

    Args:
        noise_middle: also sum J_i^T W_i J_i (`PixelEvidence.noise_middle`).
        seed: seeds each image's row subset.
    """
    lay = model.layout
    n = lay.n
    rig, gains, offset = lay.rig(x), lay.gain_factors(x), lay.offset(x)
    # Each colour channel has its lights' scales (one row without channels).
    channel_scales = np.array(
        [[light.scale for light in lay.rig(x, ch).lights] for ch in range(lay.n_channels)]
    )
    # Filled image by image (lists of parts and their concatenation held every figure
    # twice: 0.6 GB for a dense 9.5 M pixel problem). The angles and relative residuals
    # only choose and fill the diagnosis' bins: float32 (angles to 4e-6 degrees, relative
    # residuals to 6e-8 of their value) saves 12 bytes a pixel; r_noise enters chi^2.
    r_noise = np.empty(model.m)
    relative, mirror, incidence = (np.empty(model.m, dtype=np.float32) for _ in range(3))
    subsets: list[ImageRows] = []
    middle = np.zeros((n, n)) if noise_middle else None
    shares = [np.zeros(len(rig.lights))]
    grams: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    signal_all = np.empty(model.m, dtype=np.float32)
    sums = [0.0, 0.0, 0.0]  # signal^2, residual^2 (value units), r^2 (solver units)

    def exposure(i: int) -> float:
        return float(model.images[i].view.exposure)

    tested_J: list[np.ndarray] = []
    tested_r: list[np.ndarray] = []
    tested_sigma: list[np.ndarray] = []
    tested_features: list[PixelFeatures] = []

    def visit(i: int, A: np.ndarray, fluxes: np.ndarray) -> None:
        rows = slice(model.bounds[i], model.bounds[i + 1])
        n_i = A.shape[0]
        noise = meas.noise[i]
        ratio = np.empty(n_i)
        noise_residuals(
            A[:, n],
            model.sigmas[i],
            model.images[i].observed,
            offset,
            np.empty(0) if noise is None else np.array(noise, dtype=np.float64),
            r_noise[rows],
            relative[rows],
            ratio,
        )
        scales = channel_scales[model.images[i].channel]
        shares[0] = shares[0] + gains[i] * scales * fluxes.sum(axis=1)
        lit = fluxes * scales[:, None] * gains[i]
        _angles(model, i, rig.lights, lit, mirror[rows], incidence[rows])
        subset = np.arange(n_i)
        if n_i > POSE_ROWS:
            rng = np.random.default_rng([seed, i])
            subset = np.sort(rng.choice(n_i, POSE_ROWS, replace=False))
        subsets.append(ImageRows(i, subset, A[subset, :n], ratio[subset], n_i / subset.size))
        if middle is not None:
            add_weighted_gram(A, n, ratio, middle)
        J_i, r_i, sigma_i = A[:, :n], A[:, n], model.sigmas[i]
        grams.append((J_i.T @ J_i, J_i.T @ r_i, _value_gram(J_i, sigma_i)))
        sums[2] += float(r_i @ r_i)
        signal = lit.sum(axis=0)
        signal_all[rows] = signal
        residual = r_i * sigma_i
        sums[0] += float(signal @ signal)
        sums[1] += float(residual @ residual)
        rows_c = np.arange(n_i)
        if n_i > CAUSE_ROWS:
            rng = np.random.default_rng([seed, i, 1])
            rows_c = np.sort(rng.choice(n_i, CAUSE_ROWS, replace=False))
        tested_J.append(J_i[rows_c].copy())
        tested_r.append(r_i[rows_c].copy())
        tested_sigma.append(sigma_i[rows_c])
        tested_features.append(
            _features(model, i, rig.lights, lit[:, rows_c], rows_c, gains[i] * exposure(i))
        )

    model.evaluate_visiting(x, visit)
    model.release_buffers()  # not needed by the checks that follow
    tested = TestedRows(
        np.concatenate(tested_J) if tested_J else np.zeros((0, n)),
        np.concatenate(tested_r) if tested_r else np.zeros(0),
        np.concatenate(tested_sigma) if tested_sigma else np.zeros(0),
        PixelFeatures.concatenate(tested_features) if tested_features else _no_features(),
    )
    return PixelEvidence(
        r_noise,
        relative,
        mirror,
        incidence,
        subsets,
        middle,
        shares[0],
        grams,
        signal_all,
        sums[0],
        sums[1],
        sums[2],
        tested,
    )


def _value_gram(J: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """J^T diag(sigma^2) J (n, n) of J (N, n), by blocks of rows (a scaled copy of a
    dense image's J would be another (N, n) array at the checks' peak)."""
    n = J.shape[1]
    out = np.zeros((n, n))
    for c in _chunks(J.shape[0]):
        K = J[c] * sigma[c, None]
        out += K.T @ K
    return out


def _no_features() -> PixelFeatures:
    z = np.zeros(0)
    return PixelFeatures(z, z, np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 3)), z, z, z, z, z)


def _features(
    model: CalibrationModel,
    i: int,
    lights: tuple[Light, ...],
    lit: np.ndarray,
    rows: np.ndarray,
    gain: float,
) -> PixelFeatures:
    """The cause patterns' inputs (`PixelFeatures`) at rows (k,) of image i, lit (L, k)
    each light's value there; each pixel's light is the one that gives it the most."""
    im = model.images[i]
    view = im.view
    centers = im.footprints.subset(rows).centers_now()
    brightest = np.argmax(lit, axis=0) if lit.shape[0] > 1 else np.zeros(rows.size, dtype=int)
    lights_world = np.array([light.position_world(view) for light in lights])
    axes_world = np.array([light.rotation_world(view)[:, 2] for light in lights])
    to_light = lights_world[brightest] - centers
    d_light = np.linalg.norm(to_light, axis=1)
    to_camera = view.center_world[None, :] - centers
    d_camera = np.linalg.norm(to_camera, axis=1)
    cos_light = np.einsum("ij,ij->i", -to_light, axes_world[brightest]) / d_light
    ray_camera = (centers - view.center_world[None, :]) @ view.R_camera_world.T
    field_tan2 = (ray_camera[:, 0] ** 2 + ray_camera[:, 1] ** 2) / ray_camera[:, 2] ** 2
    to_light /= d_light[:, None]
    to_camera /= d_camera[:, None]
    normals = im.footprints.normals_world
    if normals is not None:  # a wall mesh: the directions in each footprint's own frame
        to_light = in_normal_frames(to_light, normals[rows])
        to_camera = in_normal_frames(to_camera, normals[rows])
    # The plane z = 0 (footprints through a camera's port carry their normal +z).
    on_plane = normals is None or bool(np.all(normals[rows] == np.array([0.0, 0.0, 1.0])))
    port_bend = (
        port_bend_pattern(centers, view, lights, brightest) if on_plane else np.zeros(rows.size)
    )
    return PixelFeatures(
        signal=lit.sum(axis=0),
        gain=np.full(rows.size, gain),
        wall_xy=centers[:, :2].copy(),
        to_light=to_light,
        to_camera=to_camera,
        d_light=d_light,
        d_camera=d_camera,
        light_angle=np.arccos(np.clip(cos_light, -1.0, 1.0)),
        field_tan2=field_tan2,
        port_bend=port_bend,
    )


def _angles(
    model: CalibrationModel,
    i: int,
    lights: tuple[Light, ...],
    lit: np.ndarray,
    mirror: np.ndarray,
    incidence: np.ndarray,
) -> None:
    """Write the mirror and incidence angles (N_i,) of image i's pixels, each for the
    light that gives it the most of its value (lit (L, N_i))."""
    im = model.images[i]
    lights_world = np.array([light.position_world(im.view) for light in lights])
    normals = im.footprints.normals_world
    for c in _chunks(len(im.footprints)):  # chunks bound the centres' temporaries
        centers = im.footprints.subset(c).centers_now()
        if normals is None:
            mirror_incidence(
                centers, lights_world, lit[:, c], im.view.center_world, mirror[c], incidence[c]
            )
            continue
        # A wall mesh: from each footprint's own normal.
        to_light = lights_world[np.argmax(lit[:, c], axis=0)] - centers
        to_light /= np.linalg.norm(to_light, axis=1, keepdims=True)
        to_camera = im.view.center_world - centers
        half = to_light + to_camera / np.linalg.norm(to_camera, axis=1, keepdims=True)
        for out, d in ((mirror, half), (incidence, to_light)):
            sin = np.linalg.norm(np.cross(d, normals[c]), axis=1)
            out[c] = np.degrees(np.arctan2(sin, np.einsum("ij,ij->i", d, normals[c])))


#: Pixels per chunk of the checks' per-pixel work (its temporaries: a few MB each).
CHUNK_PIXELS = 1 << 16


def _chunks(n: int) -> list[slice]:
    """Slices of at most CHUNK_PIXELS covering range(n)."""
    return [slice(k, min(n, k + CHUNK_PIXELS)) for k in range(0, n, CHUNK_PIXELS)]
