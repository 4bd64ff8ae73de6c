"""From a view to its expected signal, with the departures of `lightcal.synthetic.departures`.

Without departures a view's expected signal above black is the renderer's image
(`lightcal.core.render.render_image`) of the true rig, exactly as before departures
existed. With them, in this order:

1. **The beam** (`Imaging.beam`). A bowed wall is rendered by the point-sampled
   height-field renderer (`lightcal.synthetic.height_field`), a flat one by
   `render_image` (one light at a time with attenuation). Each light's contribution is
   multiplied by exp(-C d_light) (`attenuation`); the bounce of a ceiling and a side wall
   is added (`corner`, `lightcal.synthetic.bounce_reference`, attenuated along its own
   paths in water), the pixels that see them or wall they shadow masked; the pixel is
   multiplied by exp(-C d_camera) (`attenuation`) and by the albedo 1 + A t(x, y)
   (`albedo_texture`), all at the pixel centre's point on the wall (its footprint centre
   to second order in the footprint's size); then each light's backscatter along the ray
   to that point is added (`backscatter`).
2. **The sensor side** (`Imaging.expose`). The ambient level of the view (`ambient_levels`)
   times the sensor fall-off of the declared model (`map`: the map, `cos4`: cos^4, else 1)
   and, where a pixel sees the wall, its albedo texture (the wall reflects the room light
   too) is added to every pixel, also those that do not see the wall; then everything is
   multiplied by the undeclared fall-off V (`undeclared_vignetting`).

The sensor (`lightcal.synthetic.sensor.apply_sensor`) then adds noise, the black level,
the response curve (`gamma`) and rounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import SensorModel
from lightcal.core.light_port_veil import port_backscatter
from lightcal.core.medium import Medium, backscatter
from lightcal.core.render import render_image
from lightcal.core.scene import Rig, View
from lightcal.core.vignetting import RadialVignetting
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.errors import InputError
from lightcal.io.surroundings_spec import SurroundingsSpec, surroundings_spec
from lightcal.synthetic.bounce_reference import CornerBounce, corner_surroundings
from lightcal.synthetic.departures import BOW_RADIUS_M, Departures
from lightcal.synthetic.height_field import (
    BowedWall,
    point_sensor_weights,
    shade_height_field,
    surface_points,
)
from lightcal.synthetic.light_port_imaging import light_port_shading
from lightcal.synthetic.port_imaging import port_fresnel_image, port_shading
from lightcal.synthetic.texture import AlbedoTexture, sample_albedo_texture

__all__ = ["AmbientLevels", "Imaging", "ambient_levels", "make_imaging", "view_target_center"]


@dataclass(frozen=True, eq=False)
class Imaging:
    """How a view becomes its expected signal above black, DN (module docstring).

    Attributes:
        camera: The intrinsics.
        rig: The true lights, scales in DN at exposure 1.
        sensor: The declared (and true) sensor fall-off model.
        vignetting: (H, W) its map for "map", else None.
        wall: The wall's true reflectance.
        wall_shape: The bowed wall, or None for the plane z = 0.
        texture: The albedo texture, or None.
        attenuation_per_m: C of the medium, 1/m (0: none).
        backscatter_per_m, phase_g: beta of the medium's backscatter, 1/m (0: none), and
            the Henyey-Greenstein g of its scattering.
        undeclared_vignetting: (H, W) the undeclared fall-off V, or None.
        corner: The ceiling and side wall's brute-force bounce, or None.
        port: The camera's flat port the beam is seen through (`port_shading`), or None.
        light_port: The flat port every light shines through (`light_port_shading`), or
            None.
    """

    camera: Camera
    rig: Rig
    sensor: SensorModel = "radiance"
    vignetting: NDArray[np.float64] | None = None
    wall: WallReflectance = LAMBERTIAN
    wall_shape: BowedWall | None = None
    texture: AlbedoTexture | None = None
    attenuation_per_m: float = 0.0
    backscatter_per_m: float = 0.0
    phase_g: float = 0.9
    undeclared_vignetting: NDArray[np.float64] | None = None
    corner: CornerBounce | None = None
    port: FlatPort | None = None
    light_port: FlatPort | None = None

    def _render(self, view: View, rig: Rig) -> np.ma.MaskedArray:
        return render_image(
            self.camera, view, rig, sensor=self.sensor, vignetting=self.vignetting, wall=self.wall
        )

    def beam(self, view: View) -> np.ma.MaskedArray:
        """(H, W) the lights' signal, masked where the pixel does not see the wall."""
        plain = self.wall_shape is None and self.texture is None and self.corner is None
        plain = plain and self.port is None and self.light_port is None
        if plain and self.attenuation_per_m == 0.0 and self.backscatter_per_m == 0.0:
            return self._render(view, self.rig)
        camera_side: NDArray[np.float64] = view.center_world
        light_water = None  # behind the lights' port: each light's path from its port
        if self.light_port is not None:  # point-sampled, its own path solve
            per_light, points, valid, light_water = light_port_shading(
                self.camera, view, self.rig, self.light_port, sensor=self.sensor,
                vignetting=self.vignetting,
            )  # fmt: skip
        elif self.port is not None:  # point-sampled through the port, its own Snell's law
            per_light, points, valid, camera_side = port_shading(
                self.camera, view, self.rig, self.port, sensor=self.sensor,
                vignetting=self.vignetting,
            )  # fmt: skip
        elif self.wall_shape is not None:
            shading = shade_height_field(
                self.camera,
                view,
                self.rig,
                self.wall_shape,
                sensor=self.sensor,
                vignetting=self.vignetting,
                wall=self.wall,
            )
            per_light, points, valid = shading.values, shading.points_world, shading.valid
        else:
            points, valid = surface_points(self.camera, view, BowedWall(0.0))
            groups = [Rig.single(light) for light in self.rig.lights]
            if self.attenuation_per_m == 0.0:
                groups = [self.rig]
            images = [self._render(view, group) for group in groups]
            for image in images:
                valid &= ~np.ma.getmaskarray(image)
            per_light = np.stack([image.filled(np.nan) for image in images])
        if self.attenuation_per_m > 0.0:
            c = self.attenuation_per_m
            total = np.zeros(points.shape[:2])
            for k, (light, values) in enumerate(zip(self.rig.lights, per_light, strict=True)):
                d_light = np.linalg.norm(points - light.position_world(view), axis=-1)
                if light_water is not None:
                    d_light = light_water[k]
                total += values * np.exp(-c * d_light)
        else:
            total = per_light.sum(axis=0)
        if self.corner is not None:
            # the bounce arrives at the wall attenuated (`CornerBounce`); the camera's
            # segment below attenuates it as the beam
            total = total + self.corner.image_bounce(self.rig, view, points, valid)
            valid &= ~self.corner.hidden(self.rig, view, points)
        if self.attenuation_per_m > 0.0:
            d_camera = np.linalg.norm(points - camera_side, axis=-1)
            total *= np.exp(-self.attenuation_per_m * d_camera)
        if self.texture is not None:
            total = total * self.texture.factor(points[..., :2])
        if self.backscatter_per_m > 0.0:
            veil = self._backscatter(view, points, camera_side)
            if self.port is not None:  # into the camera through the port
                veil = veil * port_fresnel_image(self.camera, self.port)
            total = total + veil
        return np.ma.masked_array(np.where(valid, total, np.nan), mask=~valid)

    def declared(self, declare: bool) -> SurroundingsSpec | None:
        """The project's `surroundings` section: the corner's surfaces when `declare`."""
        if not declare or self.corner is None:
            return None
        return surroundings_spec(self.corner.surroundings)

    def _backscatter(
        self, view: View, points: NDArray[np.float64], camera_side: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """(H, W) every light's backscatter along the rays to `points` (H, W, 3) from
        `camera_side`: the camera centre (3,), or behind the port each ray's exit point
        (H, W, 3) (the water starts there); behind the lights' port, their refracted
        beams' (the renderer's kernel, every pixel exact: the test suite holds it to a
        brute-force reference)."""
        medium = Medium(self.attenuation_per_m, self.backscatter_per_m, self.phase_g)
        flat = points.reshape(-1, 3)
        start = camera_side.reshape(-1, 3)
        out = np.zeros(flat.shape[0])
        for light in self.rig.lights:
            start_ = start if len(start) > 1 else start[0]
            if self.light_port is None:
                s = backscatter(flat, start_, light, view, medium)
            else:  # the refracted beam's veil (`lightcal.core.light_port_veil`)
                ported = light.replace(port=self.light_port)
                s = port_backscatter(flat, start_, ported, view, medium)
            out += light.scale * view.exposure * medium.backscatter_per_m * s
        return out.reshape(points.shape[:2])

    def ambient(self, views: list[View], fraction: float) -> AmbientLevels:
        """The ambient levels of `views` for room light of `fraction` (`ambient_levels`
        of the views' beam peaks: every view is rendered once more)."""
        peaks = [float(self.beam(view).max()) for view in views]
        return ambient_levels(fraction, peaks, [view.exposure for view in views])

    def expose(
        self, beam: np.ma.MaskedArray, ambient_dn: float, view: View | None = None
    ) -> tuple[np.ma.MaskedArray, np.ma.MaskedArray | NDArray[np.float64]]:
        """Add the room light and the undeclared fall-off to a view's beam (H, W).

        Args:
            beam: The view's `beam`.
            ambient_dn: The view's ambient level (exposure included), DN.
            view: The view; with an albedo texture the room light the wall reflects is
                textured like the beam (where a pixel sees the wall; elsewhere, uniform).

        Returns:
            signal: (H, W) the expected signal, masked where the beam is.
            sensor_input: (H, W) what the sensor records: `signal` itself, or without a
                mask when the room light also lights the pixels that do not see the wall.
        """
        if ambient_dn == 0.0 and self.undeclared_vignetting is None:
            return beam, beam
        mask = np.ma.getmaskarray(beam)
        total = beam.filled(0.0)
        if ambient_dn > 0.0:
            falloff: NDArray[np.float64] | float = 1.0
            if self.sensor in ("map", "cos4"):
                falloff, _ = point_sensor_weights(self.camera, self.sensor, self.vignetting)
            if self.texture is not None and view is not None:
                wall = self.wall_shape if self.wall_shape is not None else BowedWall(0.0)
                points, seen = surface_points(self.camera, view, wall)
                falloff = falloff * np.where(seen, self.texture.factor(points[..., :2]), 1.0)
            if self.port is not None:  # the room light seen through the camera's port
                falloff = falloff * port_fresnel_image(self.camera, self.port)
            total = total + ambient_dn * falloff
        if self.undeclared_vignetting is not None:
            total = total * self.undeclared_vignetting
        signal = np.ma.masked_array(np.where(mask, np.nan, total), mask=mask)
        return signal, (total if ambient_dn > 0.0 else signal)


@dataclass(frozen=True)
class AmbientLevels:
    """The room light of each view (the `ambient` departure).

    Attributes:
        fraction: F.
        reference: Index of the median image (the lower median of the beam peaks).
        reference_peak_dn: The brightest beam value of that image, DN.
        reference_exposure: Its relative exposure.
        per_exposure_dn: The ambient level at relative exposure 1, DN:
            F reference_peak_dn / exposure of the reference.
        levels_dn: (n_views,) each view's level, per_exposure_dn times its exposure.
    """

    fraction: float
    reference: int
    reference_peak_dn: float
    reference_exposure: float
    per_exposure_dn: float
    levels_dn: tuple[float, ...]


def ambient_levels(fraction: float, peaks_dn: list[float], exposures: list[float]) -> AmbientLevels:
    """The ambient level of every view (`Departures.ambient_fraction`).

    Args:
        fraction: F >= 0.
        peaks_dn: (n,) the brightest beam value of each view, DN.
        exposures: (n,) the views' relative exposures.
    """
    order = np.argsort(np.asarray(peaks_dn), kind="stable")
    ref = int(order[(len(order) - 1) // 2])
    per_exposure = fraction * peaks_dn[ref] / exposures[ref]
    return AmbientLevels(
        fraction=fraction,
        reference=ref,
        reference_peak_dn=float(peaks_dn[ref]),
        reference_exposure=float(exposures[ref]),
        per_exposure_dn=float(per_exposure),
        levels_dn=tuple(float(per_exposure * g) for g in exposures),
    )


def view_target_center(views: list[View]) -> tuple[float, float]:
    """(x0, y0) the mean of the points where the views' optical axes meet z = 0, metres."""
    hits = []
    for view in views:
        axis = view.R_camera_world[2]  # the optical axis, world frame
        center = view.center_world
        hits.append(center[:2] - center[2] / axis[2] * axis[:2])
    x0, y0 = np.mean(hits, axis=0)
    return float(x0), float(y0)


def make_imaging(
    camera: Camera,
    views: list[View],
    rig: Rig,
    departures: Departures,
    rng_texture: np.random.Generator,
    *,
    sensor: SensorModel = "radiance",
    vignetting: NDArray[np.float64] | None = None,
    wall: WallReflectance = LAMBERTIAN,
) -> Imaging:
    """The imaging of a dataset: its true scene and the departures' fixed parts.

    Args:
        camera: The intrinsics.
        views: The true views (the bow is centred where they look).
        rig: The true lights, scales in DN.
        departures: What departs from the project.
        rng_texture: Randomness of the albedo texture (unused without one).
        sensor: The sensor fall-off model.
        vignetting: (H, W) the map of "map".
        wall: The wall's true reflectance.

    Raises:
        InputError: the undeclared fall-off reaches 0 or below inside the image.
    """
    if departures.corner is not None and sensor != "radiance":
        raise InputError("corner", f"applies to the radiance sensor model only, got {sensor!r}")
    corner = None
    if departures.corner is not None:
        distance, depth, albedo = departures.corner
        target = view_target_center(views)
        corner = CornerBounce(
            corner_surroundings(target, distance, depth, albedo),
            _wall_extent(camera, views),
            attenuation_per_m=departures.attenuation_per_m,
        )
    if departures.backscatter_per_m > 0.0 and sensor != "radiance":
        raise InputError(
            "backscatter_per_m", f"applies to the radiance sensor model only, got {sensor!r}"
        )
    wall_shape = None
    if departures.bow_m != 0.0:
        wall_shape = BowedWall(departures.bow_m, view_target_center(views), BOW_RADIUS_M)
    texture = None
    if departures.albedo_texture_amplitude > 0.0:
        texture = sample_albedo_texture(departures.albedo_texture_amplitude, rng_texture)
    undeclared = None
    if departures.undeclared_vignetting is not None:
        model = RadialVignetting.centered(
            np.array(departures.undeclared_vignetting), width=camera.width, height=camera.height
        )
        undeclared = model.image()
        if not np.all(undeclared > 0.0):
            raise InputError(
                "undeclared_vignetting",
                f"the fall-off reaches {float(undeclared.min()):.3g} inside the image; "
                "expected V > 0 everywhere",
            )
    port = None
    if departures.port is not None:
        if wall_shape is not None or texture is not None or corner is not None:
            raise InputError("port", "not rendered with a bowed wall, a texture or a corner")
        if not wall.is_lambertian or sensor == "paper":
            raise InputError("port", "not rendered with a non-Lambertian wall or 'paper'")
        d_mm, t_mm, n_g, n_w = departures.port
        port = FlatPort(d_mm / 1000.0, t_mm / 1000.0, n_g, n_w)
    return Imaging(
        camera=camera,
        rig=rig,
        sensor=sensor,
        vignetting=vignetting,
        wall=wall,
        wall_shape=wall_shape,
        texture=texture,
        attenuation_per_m=departures.attenuation_per_m,
        backscatter_per_m=departures.backscatter_per_m,
        phase_g=departures.phase_g,
        undeclared_vignetting=undeclared,
        corner=corner,
        port=port,
        light_port=_light_port(departures, wall, sensor, (wall_shape, texture, corner)),
    )


def _light_port(
    departures: Departures, wall: WallReflectance, sensor: SensorModel, shapes: tuple
) -> FlatPort | None:
    """The lights' port of the `light_port` departure, or None; InputError for what
    `light_port_shading` does not render."""
    if departures.light_port is None:
        return None
    if departures.port is not None or any(shape is not None for shape in shapes):
        raise InputError(
            "light_port", "not rendered with a camera port, a bowed wall, a texture or a corner"
        )
    if not wall.is_lambertian or sensor == "paper":
        raise InputError("light_port", "not rendered with a non-Lambertian wall or 'paper'")
    d_mm, t_mm, n_g, n_w = departures.light_port
    return FlatPort(d_mm / 1000.0, t_mm / 1000.0, n_g, n_w)


def _wall_extent(camera: Camera, views: list[View]) -> tuple[float, float, float, float]:
    """(x0, x1, y0, y1) the wall the views' pixels see and 0.5 m more, m."""
    pts = []
    for view in views:
        points, valid = surface_points(camera, view, BowedWall(0.0))
        pts.append(points[valid])
    p = np.concatenate(pts)
    lo, hi = p.min(axis=0) - 0.5, p.max(axis=0) + 0.5
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])
