"""The candidate causes of a misfit the fit test weighs, as columns (`lightcal.core.alternatives`).

Each cause is a model extension at "no effect", written as the change of the rendered
value it makes per unit of its parameters. Most are multiplicative: columns
c = (m_render - offset) q(pixel) with a dimensionless pattern q; the ambient cause is
additive. The patterns (`PixelFeatures` gives their inputs, per pixel):

- `gloss` (4): D_GGX(h . n; alpha) / (4 mu_l mu_v) for alpha 0.1, 0.25 and 0.5, and the
  coat's transmittance (1 - F(mu_l)) (1 - F(mu_v)) (ior 1.5): a glossy paint, the
  `plastic` wall's two parts;
- `rough_matte` (1): the Oren-Nayar term's derivative in sigma^2 at 0: a rough matte wall;
- `profile` (8): hat functions of the angle from the light's axis: a wrong RID (a bright
  rim, another width);
- `ambient` (2, additive): g_i (room light, which scales with the exposure) and 1 (a
  wrong black level);
- `vignetting` (2): s and s^2, s = tan^2 of the ray's angle to the optical axis over its
  largest: a lens fall-off the project does not declare;
- `response` (2): ln(m / median m) and its square: a non-linear (gamma, JPEG) response;
- `medium` (1): d_light + d_camera (m): absorption in water or haze;
- `port` (1): d ln E / d eps, the irradiance's change where the footprint moves when an
  interface of index 1 + eps bends the camera's rays toward its axis
  (`lightcal.core.port_bend`): a flat port (a camera housing's window) the project does
  not declare;
- `wall` (up to 64): indicators of up to 8 x 8 cells (about 50 tested pixels a cell) over
  the tested pixels' extent on the wall: uneven albedo, a bowed wall, light from the
  surroundings.

(The per-image cause, "the images disagree", is built from each image's own Jacobian:
`lightcal.pipeline.fit_check`.) Each pattern is normalised to unit maximum magnitude
(the tests do not depend on the columns' scale).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Most cells a side of the `wall` cause's grid over the tested pixels' extent on the
#: wall (fewer with few pixels: about `WALL_CELL_PIXELS` a cell).
WALL_CELLS = 8
WALL_CELL_PIXELS = 50
#: Fewest pixels a `wall` cell needs to get a column.
WALL_CELL_MIN = 10
#: Hat functions of the `profile` cause over 0 .. the largest angle from the light's axis.
PROFILE_KNOTS = 8
#: GGX roughnesses of the `gloss` cause's lobes.
GLOSS_ALPHAS = (0.1, 0.25, 0.5)
#: Index of refraction of the `gloss` cause's coat (its Fresnel transmittance column).
GLOSS_IOR = 1.5


@dataclass(frozen=True)
class Cause:
    """One candidate cause: its name, what it means and what to do about it.

    Attributes:
        name: the key in the result (`fit.causes`).
        meaning: what the residuals look like, in words, for the finding.
        advice: what to try.
    """

    name: str
    meaning: str
    advice: str


CAUSES: dict[str, Cause] = {
    c.name: c
    for c in (
        Cause(
            "gloss",
            "the wall is brighter than the model toward the mirror direction: it looks glossy",
            "try `wall: {model: plastic}` (or `auto`), or `selection.exclude_mirror_deg`",
        ),
        Cause(
            "rough_matte",
            "the wall reflects like a rough matte surface (retro-reflection), not a Lambertian one",
            "try `wall: {model: oren_nayar}` (or `auto`)",
        ),
        Cause(
            "profile",
            "the residuals follow the angle from the light's axis: the light's angular "
            "profile (RID) differs from the one given (a bright rim, another width; in "
            "water, a flat window in front of the light narrows its beam)",
            "check the RID file, declare the light's port in water (`lights[i].port`), or "
            "estimate the RID (`estimate_rid: curve`)",
        ),
        Cause(
            "ambient",
            "a constant light adds to every pixel: room light, or a wrong black level",
            "set `sensor.estimate_ambient: true` (room light, which grows with each image's "
            "exposure) or `sensor.estimate_offset: true` (a black level, the same in every "
            "image), or turn the room light off",
        ),
        Cause(
            "vignetting",
            "the residuals fall off toward the image corners: a lens fall-off "
            "(vignetting) the project does not declare",
            "declare the fall-off (`sensor: {model: map}` with a flat-field, or `cos4`), or "
            "estimate it with the light (`sensor.estimate_fall_off: {order: 2}`, with views "
            "at several distances)",
        ),
        Cause(
            "response",
            "the residuals grow with the brightness itself: the images are not linear "
            "(a gamma or JPEG tone curve)",
            "use raw or linear images, or give the camera's response curve",
        ),
        Cause(
            "medium",
            "the residuals fall off with the light's path length: the light is absorbed on "
            "its way (water, haze)",
            "photograph in air, or declare the water (medium: its attenuation estimated)",
        ),
        Cause(
            "port",
            "the wall is seen as if through a flat window in water: each footprint lies "
            "nearer the camera's axis than straight rays put it (a camera housing's port)",
            "declare the camera's port (`camera.port: {distance_mm, thickness_mm, "
            "glass_index, water_index}`), or check the one declared",
        ),
        Cause(
            "wall",
            "the residuals follow the position on the wall, the same in every view: uneven "
            "albedo, a wall that is not flat, or light from the surroundings",
            "use a flat, evenly white wall away from other surfaces, mask the uneven parts, "
            "or estimate the wall's albedo map (wall.albedo_map, with a dense selection)",
        ),
        Cause(
            "images",
            "each image wants its own light pose: the images disagree with each other",
            "check the camera poses (markers, SfM) and the exposures, and that the light "
            "did not move on its mount",
        ),
    )
}


@dataclass(frozen=True)
class PixelFeatures:
    """What the cause patterns need of each tested pixel (all (N,) unless noted).

    Attributes:
        signal: m_render - offset, value units (every light, at the solution).
        gain: the image's exposure gain g_i (value per unit scale).
        wall_xy: (N, 2) footprint centre on the wall, m.
        to_light: (N, 3) unit direction from the footprint centre to the brightest light.
        to_camera: (N, 3) unit direction from the footprint centre to the camera.
        d_light, d_camera: the distances to them, m.
        light_angle: angle between the brightest light's axis and the direction to the
            pixel, radians.
        field_tan2: tan^2 of the angle between the camera's optical axis and the ray.
        port_bend: d ln E / d eps where a flat port of index 1 + eps moves the footprint
            (`lightcal.core.port_bend.port_bend_pattern`, from the camera's centre also
            behind a declared port; 0 on a wall mesh).
    """

    signal: np.ndarray
    gain: np.ndarray
    wall_xy: np.ndarray
    to_light: np.ndarray
    to_camera: np.ndarray
    d_light: np.ndarray
    d_camera: np.ndarray
    light_angle: np.ndarray
    field_tan2: np.ndarray
    port_bend: np.ndarray

    @staticmethod
    def concatenate(parts: list[PixelFeatures]) -> PixelFeatures:
        """One `PixelFeatures` of the rows of every part, in order."""
        fields = PixelFeatures.__dataclass_fields__
        return PixelFeatures(
            **{name: np.concatenate([getattr(p, name) for p in parts]) for name in fields}
        )


def _unit_max(q: np.ndarray) -> np.ndarray:
    """q (N, k) with each column scaled to unit largest magnitude (zero columns kept)."""
    top = np.max(np.abs(q), axis=0) if q.size else np.zeros(q.shape[1])
    return q / np.where(top > 0.0, top, 1.0)


def _gloss(f: PixelFeatures) -> np.ndarray:
    h = f.to_light + f.to_camera
    cos_h = np.clip(h[:, 2] / np.linalg.norm(h, axis=1), 0.0, 1.0)
    mu_l = np.maximum(f.to_light[:, 2], 1e-3)
    mu_v = np.maximum(f.to_camera[:, 2], 1e-3)
    cols = []
    for alpha in GLOSS_ALPHAS:
        a2 = alpha * alpha
        D = a2 / (math.pi * (1.0 + (a2 - 1.0) * cos_h**2) ** 2)
        cols.append(D / (4.0 * mu_l * mu_v))
    cols.append((1.0 - _fresnel(mu_l, GLOSS_IOR)) * (1.0 - _fresnel(mu_v, GLOSS_IOR)))
    return np.stack(cols, axis=1)


def _fresnel(c: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a dielectric of index eta at cosine c (N,)."""
    g = np.sqrt(eta * eta - 1.0 + c * c)
    rs = (c - g) / (c + g)
    rp = (eta * eta * c - g) / (eta * eta * c + g)
    return 0.5 * (rs * rs + rp * rp)


def _rough_matte(f: PixelFeatures) -> np.ndarray:
    # Oren-Nayar: A - 1 + B max(0, l_t . v_t) / max(mu_l, mu_v), A = 1 - 0.5 s2 / (s2 + 0.33),
    # B = 0.45 s2 / (s2 + 0.09): d / d s2 at 0 is -0.5 / 0.33 + 5 max(0, l_t . v_t) / max(mu).
    lt = f.to_light[:, :2]
    vt = f.to_camera[:, :2]
    dot = np.maximum(np.sum(lt * vt, axis=1), 0.0)
    mu = np.maximum(np.maximum(f.to_light[:, 2], f.to_camera[:, 2]), 1e-3)
    return (-0.5 / 0.33 + (0.45 / 0.09) * dot / mu)[:, None]


def _profile(f: PixelFeatures) -> np.ndarray:
    top = float(f.light_angle.max()) if f.light_angle.size else 0.0
    if not top > 0.0:
        return np.zeros((f.signal.size, 0))
    knots = np.linspace(0.0, top, PROFILE_KNOTS)
    h = knots[1] - knots[0]
    return np.maximum(1.0 - np.abs(f.light_angle[:, None] - knots[None, :]) / h, 0.0)


def _vignetting(f: PixelFeatures) -> np.ndarray:
    top = float(f.field_tan2.max()) if f.field_tan2.size else 0.0
    s = f.field_tan2 / top if top > 0.0 else f.field_tan2
    return np.stack([s, s * s], axis=1)


def _response(f: PixelFeatures) -> np.ndarray:
    level = np.maximum(f.signal, 1e-12)
    t = np.log(level / float(np.median(level)))
    return np.stack([t, t * t], axis=1)


def _medium(f: PixelFeatures) -> np.ndarray:
    return (f.d_light + f.d_camera)[:, None]


def _port(f: PixelFeatures) -> np.ndarray:
    if not np.any(f.port_bend):
        return np.zeros((f.signal.size, 0))
    return f.port_bend[:, None]


def _wall(f: PixelFeatures) -> np.ndarray:
    xy = f.wall_xy
    if xy.shape[0] == 0:
        return np.zeros((0, 0))
    lo = xy.min(axis=0)
    span = float(np.max(xy.max(axis=0) - lo))
    if not span > 0.0:
        return np.zeros((xy.shape[0], 0))
    side = int(min(WALL_CELLS, max(2, math.isqrt(xy.shape[0] // WALL_CELL_PIXELS))))
    cell = np.minimum((xy - lo) / span * side, side - 1).astype(np.int64)
    index = cell[:, 0] * side + cell[:, 1]
    counts = np.bincount(index, minlength=side * side)
    used = np.flatnonzero(counts >= WALL_CELL_MIN)
    q = np.zeros((xy.shape[0], used.size))
    column = np.full(side * side, -1)
    column[used] = np.arange(used.size)
    rows = np.flatnonzero(column[index] >= 0)
    q[rows, column[index[rows]]] = 1.0
    return q


_MULTIPLICATIVE = {
    "gloss": _gloss,
    "rough_matte": _rough_matte,
    "profile": _profile,
    "vignetting": _vignetting,
    "response": _response,
    "medium": _medium,
    "port": _port,
    "wall": _wall,
}


#: The sign each cause's coefficients must have (physics; 0: either). Gloss adds light
#: toward the mirror direction and its coat darkens grazing angles, a rough matte wall
#: brightens toward the light (sigma^2 >= 0), room light adds, absorption takes away,
#: water behind a port is denser than air (eps >= 0).
SIGNS: dict[str, tuple[int, ...]] = {
    "gloss": (1,) * (len(GLOSS_ALPHAS) + 1),
    "rough_matte": (1,),
    "ambient": (1, 0),
    "medium": (-1,),
    "port": (1,),
}


def cause_columns(f: PixelFeatures) -> dict[str, tuple[np.ndarray, np.ndarray | None]]:
    """Per cause (`CAUSES` but `images`): its columns C (N, k) in value units and the
    signs (k,) their coefficients must have (None: free)."""
    out: dict[str, tuple[np.ndarray, np.ndarray | None]] = {}
    for name, pattern in _MULTIPLICATIVE.items():
        q = pattern(f)
        C = f.signal[:, None] * _unit_max(q) if q.size else np.zeros((f.signal.size, 0))
        out[name] = (C, _signs(name, C.shape[1]))
    out["ambient"] = (np.stack([f.gain, np.ones_like(f.gain)], axis=1), _signs("ambient", 2))
    return out


def _signs(name: str, k: int) -> np.ndarray | None:
    signs = SIGNS.get(name)
    if signs is None or len(signs) != k:
        return None
    return np.array(signs, dtype=np.float64)
