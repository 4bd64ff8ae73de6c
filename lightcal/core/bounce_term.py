"""The bounce term of a calibration's images (docs/model.md, "Inter-reflection"): each
light's bounce flux per unit scale into the selected pixels, in air or in a medium, with
its derivatives with respect to the light's pose and the medium's attenuation c.

The world-fixed radiosity is `lightcal.core.bounce.BounceMap`. In a homogeneous absorbing
medium of attenuation c (1/m) every segment of a bounce path is attenuated: light ->
copy or wall node (the sources), copy <-> copy and copy <-> wall (the transfers), and the
wall point -> camera, exp(-c |P - C_i|) at the footprint centre P as for the direct
light. With L(c) the copies' radiance and P(c) the map from it to the pixels,

    bounce = T_cam P L,   d bounce / dc = T_cam (P' L + P L') - |P - C_i| bounce,

P' and L' from the transfers' slopes (`lightcal.core.bounce_transfers`). The veil the
bounce light itself scatters into the camera (backscatter) is not modelled.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from lightcal.core.bounce import BounceMap
from lightcal.core.bounce_pixels import PixelMap
from lightcal.core.bounce_transfers import albedo_slopes, radiance_slope
from lightcal.core.footprint import Footprints
from lightcal.core.medium import AIR, Medium
from lightcal.core.scene import Light, Rig, View
from lightcal.core.surroundings import Surroundings

__all__ = ["MARGIN_M", "BounceTerm"]

#: The wall grid reaches MARGIN_M beyond the pixels: wall the beam lights outside the
#: images also lights the surfaces, m.
MARGIN_M = 0.5

#: The last maps built: (surroundings, region, map); a calibration's stages (a first solve
#: on a subset of its pixels, the mirror exclusion, `wall: auto`) share one.
_MAPS: list[tuple[Surroundings, tuple[float, float, float, float], BounceMap]] = []


def _shared_map(
    surroundings: Surroundings, region_xy: tuple[float, float, float, float]
) -> BounceMap:
    """A recent `BounceMap` of the same surroundings whose region holds `region_xy`, or
    a new one (kept with the last three)."""
    x0, x1, y0, y1 = region_xy
    for s, (a0, a1, b0, b1), found in _MAPS:
        if s is surroundings and a0 <= x0 and x1 <= a1 and b0 <= y0 and y1 <= b1:
            return found
    made = BounceMap(surroundings, region_xy)
    _MAPS.append((surroundings, region_xy, made))
    del _MAPS[:-4]
    return made


def _coverage(footprints: Footprints) -> np.ndarray:
    """(N,) sum over each footprint's quads of sensor weight x area: the value of a
    uniform irradiance of 1 (1 for the `radiance` sensor model)."""
    q = footprints.corners_world
    d = np.cross(q[:, :, 2] - q[:, :, 0], q[:, :, 3] - q[:, :, 1])
    area = 0.5 * np.linalg.norm(d, axis=-1)
    return np.nan_to_num(np.einsum("nk,nk->n", footprints.weights, area))


#: An image's near copies in a medium: (c, their sparse map, its slope d/dc or None).
_Near = tuple[float, sparse.csr_matrix, sparse.csr_matrix | None]


class BounceTerm:
    """The bounce term of a calibration's images: each light's bounce flux per unit
    scale into their pixels, with its derivatives.

    Args:
        surroundings: the surfaces.
        footprints: each image's selected pixels.
    """

    def __init__(self, surroundings: Surroundings, footprints: list[Footprints]) -> None:
        centres = [fp.corners_world.mean(axis=(1, 2)) for fp in footprints]
        known = np.concatenate([c[np.all(np.isfinite(c), axis=1)] for c in centres])
        if known.size == 0:
            known = np.zeros((1, 3))
        lo, hi = known.min(axis=0), known.max(axis=0)
        m = MARGIN_M
        self.map = _shared_map(surroundings, (lo[0] - m, hi[0] + m, lo[1] - m, hi[1] + m))
        self.coverage = [_coverage(fp) for fp in footprints]
        self.centers_world = [np.where(np.isfinite(c), c, lo) for c in centres]
        self.pixels = [self.map.pixel_map(c) for c in self.centers_world]
        # Per image, the near copies' sparse maps in a medium: (c, near, its slope or None).
        self._near: list[_Near | None] = [None] * len(footprints)
        self.estimated = surroundings.estimate_albedo  # the surfaces whose albedo is solved

    @classmethod
    def of(
        cls, surroundings: Surroundings | None, footprints: list[Footprints]
    ) -> BounceTerm | None:
        """The bounce term of `surroundings` (None: none) for images' footprints."""
        return None if surroundings is None else cls(surroundings, footprints)

    def add(
        self,
        i: int,
        view: View,
        light: Light,
        flux: np.ndarray,
        grad: np.ndarray | None,
        medium: Medium = AIR,
        d_attenuation: np.ndarray | None = None,
        albedos: np.ndarray | None = None,
        d_albedo: np.ndarray | None = None,
    ) -> None:
        """Add image i's bounce to a light's flux (N_i,) and its gradients (N_i, 6) (as
        `render.light_flux` gives them, per unit scale), in place; with d_attenuation
        (N_i,) and grad, its derivative with respect to the medium's c too. `albedos`
        (S,): the surfaces' albedos (None: the declared); d_albedo (N_i, m), with grad,
        gains the derivatives with respect to the albedos the surroundings estimate
        (`Surroundings.estimate_albedo`)."""
        want_dc = grad is not None and d_attenuation is not None
        estimated = self.estimated if grad is not None and d_albedo is not None else ()
        b = self.flux(
            i,
            view,
            light,
            want_grad=grad is not None,
            medium=medium,
            want_dc=want_dc,
            albedos=albedos,
            albedo_surfaces=estimated,
        )
        flux += b[:, 0]
        if grad is not None:
            grad += b[:, 1:7]
        if want_dc:
            assert d_attenuation is not None
            d_attenuation += b[:, 7]
        if estimated:
            assert d_albedo is not None
            d_albedo += b[:, -len(estimated) :]

    def values(
        self, i: int, view: View, rig: Rig, medium: Medium = AIR, albedos: np.ndarray | None = None
    ) -> np.ndarray:
        """(N_i,) image i's bounce value: the sum over the rig's lights of scale x flux."""
        return np.asarray(
            sum(
                light.scale
                * self.flux(i, view, light, want_grad=False, medium=medium, albedos=albedos)[:, 0]
                for light in rig.lights
            )
        )

    def flux(
        self,
        i: int,
        view: View,
        light: Light,
        *,
        want_grad: bool,
        medium: Medium = AIR,
        want_dc: bool = False,
        albedos: np.ndarray | None = None,
        albedo_surfaces: tuple[int, ...] = (),
    ) -> np.ndarray:
        """(N_i, 1 or 7, + 1 with want_dc, + m) image i's bounce flux per unit scale
        (exposure included), with want_grad d / d (L_world (3), delta_world (3)) as
        `render.light_flux`, with want_dc (the column after) d / dc, c the medium's
        attenuation (1/m), and last d / d a_k of the m surfaces `albedo_surfaces`, the
        surfaces' albedos `albedos` (S,) (None: the declared)."""
        L_world = light.position_world(view)
        n = len(self.coverage[i])
        if L_world[2] <= 0.0:  # a light on or behind the wall lights nothing
            return np.zeros((n, (7 if want_grad else 1) + want_dc + len(albedo_surfaces)))
        c = medium.attenuation_per_m
        if c == 0.0 and not want_dc and albedos is None and not albedo_surfaces:  # as built
            src = self.map.source_columns(
                L_world, light.rotation_world(view), light.rid, want_grad=want_grad
            )
            b = self.map.bounce(self.map.radiance(src), self.pixels[i])
        else:
            b = self._in_medium(
                i, view, light, c, want_grad, want_dc, albedos, tuple(albedo_surfaces)
            )
        return b * (view.exposure * self.coverage[i])[:, None]

    def _in_medium(
        self,
        i: int,
        view: View,
        light: Light,
        c: float,
        want_grad: bool,
        want_dc: bool,
        albedos: np.ndarray | None,
        albedo_surfaces: tuple[int, ...],
    ) -> np.ndarray:
        """`flux` in a medium of attenuation c (0: air) with the surfaces' albedos,
        before the exposure and the sensor's weights."""
        L_world = light.position_world(view)
        bm = self.map
        t, d = bm.transfers_at(c, albedos, want_slopes=want_dc)
        src = bm.source_columns(
            L_world, light.rotation_world(view), light.rid, want_grad=want_grad, attenuation_per_m=c
        )
        radiance = t.radiance(src)
        near, near_dc = self._near_at(i, c, want_dc)
        if want_dc:
            assert d is not None and near_dc is not None
            src_dc = -bm.source_distances(L_world) * src[:, 0]
            radiance_dc = radiance_slope(t, d, src[:, 0], src_dc, radiance[:, 0])
            radiance = np.column_stack([radiance, radiance_dc])
        dc = radiance.shape[1] - 1  # the column of d/dc, with want_dc
        if albedo_surfaces:
            masks = bm.surface_masks(albedo_surfaces)
            slopes = albedo_slopes(t, src[:, 0], radiance[:, 0], masks)
            radiance = np.column_stack([radiance, slopes])
        pixels = self.pixels[i]
        b = np.asarray(pixels.gather(t.G_WS, radiance) + near @ radiance)
        if want_dc:
            assert d is not None and near_dc is not None
            b[:, dc] += pixels.gather(d.D_WS, radiance[:, :1])[:, 0] + near_dc @ radiance[:, 0]
        to_camera_m = np.linalg.norm(self.centers_world[i] - view.center_world, axis=1)
        b *= np.exp(-c * to_camera_m)[:, None]
        if want_dc:
            b[:, dc] -= to_camera_m * b[:, 0]
        return b

    def _near_at(
        self, i: int, c: float, want_dc: bool
    ) -> tuple[sparse.csr_matrix, sparse.csr_matrix | None]:
        """Image i's near copies' sparse map (N_i, K) in the medium of attenuation c and,
        with want_dc, its derivative; kept for the last c."""
        kept = self._near[i]
        if kept is None or kept[0] != c or (want_dc and kept[2] is None):
            t, d = self.map.in_medium(c, want_slopes=want_dc)
            pixels: PixelMap = self.pixels[i]
            shape = pixels.near.shape
            near = pixels.near if c == 0.0 else pixels.pairs.near(t.G_WS, shape, c)
            slope = None if d is None else pixels.pairs.near_slope(d.D_WS, shape, c)
            kept = (c, near, slope)
            self._near[i] = kept
        return kept[1], kept[2]
