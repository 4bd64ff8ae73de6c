"""The pictures on the camera frusta: real, rendered or residual images, downscaled.

Exact values stay on the server; what goes to the browsers is an RGB picture of at
most `max_side` pixels on its long side, JPEG-encoded by viser. Rendered images use
the camera binned so that the long side has about `render_side` pixels
(`Camera.binned`): one footprint per super-pixel, which is what a display needs and
~b^2 times cheaper than the exact binned render. The residual (real minus rendered) is
compared on the same binned grid (`bin_values`) and shown with a diverging colour map
on a symmetric scale shared by all images (the legend).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import cv2
import numpy as np

from lightcal.colormap import diverging_rgb, grey_rgb, robust_vmax
from lightcal.core.albedo_map import with_albedo
from lightcal.core.bounce_image import BounceImages
from lightcal.core.camera import Camera
from lightcal.core.footprint import SensorModel
from lightcal.core.medium import Medium
from lightcal.core.port_render import render_view_image, room_light_view
from lightcal.core.problem import with_view
from lightcal.core.quantiles import percentile
from lightcal.core.selection import bin_values
from lightcal.core.surroundings import Surroundings
from lightcal.io.project import Project
from lightcal.pipeline import LoadedImages
from lightcal.pipeline.albedo_result import albedo_image
from lightcal_app.state import Display, OverlayKind, UserRegion

INCLUDE_RGB = (40, 210, 60)
EXCLUDE_RGB = (235, 40, 40)
SELECTED_RGB = (40, 230, 90)
POINT_RGB = (255, 215, 0)
MASK_RGB = np.array([200, 0, 200], dtype=np.float64)
OUTLINE_FRACTION = 0.05
"""A selection covering more of a picture than this is drawn as its outline."""
BOUNCE_KEPT = 3
"""The surroundings' bounce maps kept (each takes seconds to build): the latest edits'."""


def bounce_key(surroundings: Surroundings) -> str:
    """What the bounce light of `surroundings` depends on, as text (equal text: equal
    surroundings)."""
    return json.dumps(surroundings.describe(), sort_keys=True)


@dataclass(frozen=True)
class DisplayGeometry:
    """Sizes of one project's pictures.

    Attributes:
        camera: intrinsics of the images as loaded (W x H).
        render_binning: b of the rendered (and residual) images.
        render_camera: `camera.binned(render_binning)`.
        width, height: size of the pictures sent to the browsers.
    """

    camera: Camera
    render_binning: int
    render_camera: Camera
    width: int
    height: int


def display_geometry(
    camera: Camera, *, max_side: int = 640, render_side: int = 200
) -> DisplayGeometry:
    """Sizes for a camera: pictures of long side <= max_side, renders of ~render_side."""
    long_side = max(camera.width, camera.height)
    b = max(1, math.ceil(long_side / render_side))
    s = min(1.0, max_side / long_side)
    w = max(1, round(camera.width * s))
    h = max(1, round(camera.height * s))
    return DisplayGeometry(camera, b, camera.binned(b) if b > 1 else camera, w, h)


def full_to_display(points_px: np.ndarray, geo: DisplayGeometry) -> np.ndarray:
    """(N, 2) full-resolution pixel coordinates -> picture coordinates (centres at integers)."""
    p = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    sx = geo.width / geo.camera.width
    sy = geo.height / geo.camera.height
    return np.stack([(p[:, 0] + 0.5) * sx - 0.5, (p[:, 1] + 0.5) * sy - 0.5], axis=1)


def binned_to_full(points: np.ndarray, binning: int) -> np.ndarray:
    """(N, 2) pixel indices of a b x b binned grid -> full-resolution centre coordinates."""
    return (np.asarray(points, dtype=np.float64).reshape(-1, 2) + 0.5) * binning - 0.5


class OverlayImages:
    """The pictures of one project's images.

    Args:
        project: the project.
        loaded: its images.
        max_side, render_side: see `display_geometry`.
    """

    def __init__(
        self, project: Project, loaded: LoadedImages, *, max_side: int = 640, render_side: int = 200
    ) -> None:
        self.project = project
        self.loaded = loaded
        self.geo = display_geometry(loaded.camera, max_side=max_side, render_side=render_side)
        b = self.geo.render_binning
        self.real_rgb: list[np.ndarray] = []
        self.real_binned: list[np.ndarray] = []
        self.white: list[float] = []
        self.mask_display: list[np.ndarray] = []
        for i, img in enumerate(loaded.images):
            values = np.where(img.saturated, np.nan, img.values)
            finite = values[np.isfinite(values)]
            white = percentile(finite, 99.5) if finite.size else 1.0
            white = white if white > 0 else 1.0
            self.white.append(white)
            self.real_rgb.append(self._resize(grey_rgb(img.values, white)))
            binned = bin_values(values, b) if b > 1 else values
            self.real_binned.append(binned)
            bad = img.saturated.astype(np.float32)
            if loaded.excluded[i] is not None:
                bad = np.maximum(bad, np.asarray(loaded.excluded[i], dtype=np.float32))
            small = cv2.resize(bad, (self.geo.width, self.geo.height), interpolation=cv2.INTER_AREA)
            self.mask_display.append(small > 0.0)
        self._vignetting = self._binned_vignetting()
        # Per sensor model and surroundings (`bounce_key`), their bounce light in the views,
        # built when first drawn: an edit of the surroundings in the page makes another.
        self._bounce: dict[tuple[str, str], BounceImages] = {}
        shape = (self.geo.height, self.geo.width, 3)
        self._mask_colour = np.empty(shape, np.uint8)
        self._mask_colour[:] = MASK_RGB.astype(np.uint8)
        self._selected_colour = np.empty(shape, np.uint8)
        self._selected_colour[:] = SELECTED_RGB

    def _resize(self, rgb: np.ndarray, *, nearest: bool = False) -> np.ndarray:
        h, w = rgb.shape[:2]
        if (w, h) == (self.geo.width, self.geo.height):
            return rgb
        if nearest:
            interp = cv2.INTER_NEAREST
        else:
            interp = cv2.INTER_AREA if w > self.geo.width else cv2.INTER_LINEAR
        return cv2.resize(rgb, (self.geo.width, self.geo.height), interpolation=interp)

    def _binned_vignetting(self) -> np.ndarray | None:
        p = self.project
        if p.vignetting_path is None:  # (with a file, the Solve tab may choose "map")
            return None
        from lightcal.io.vignetting_file import load_vignetting

        cam = self.geo.camera
        vmap = load_vignetting(p.vignetting_path, width=cam.width, height=cam.height)
        b = self.geo.render_binning
        return bin_values(vmap, b) if b > 1 else vmap

    def _bounce_images(self, sensor: SensorModel, surroundings: Surroundings) -> BounceImages:
        """The bounce light of `surroundings` in the views (the last `BOUNCE_KEPT` kept)."""
        key = (sensor, bounce_key(surroundings))
        images = self._bounce.pop(key, None)
        if images is None:
            images = BounceImages(
                self.geo.render_camera,
                self.project.views,
                surroundings,
                sensor=sensor,
                vignetting=self._vignetting,
            )
        self._bounce[key] = images  # the newest last
        while len(self._bounce) > BOUNCE_KEPT:
            del self._bounce[next(iter(self._bounce))]
        return images

    def render(self, index: int, display: Display) -> np.ma.MaskedArray:
        """(h, w) rendered values of image `index` on the binned grid (masked off the wall),
        as the model has them: the estimated room light, fall-off and albedo map in."""
        display = display.of_channel(self.project.channel_index(index))
        view = self.project.views[index]
        view = with_view(view, exposure=view.exposure * display.gains[index])
        sensor = display.fall_off or self.project.spec.sensor.model
        bounce: float | np.ndarray = 0.0  # the surroundings' light, as the model adds it
        surroundings = display.surroundings  # the solve's: as the page edits them
        if surroundings is not None:  # (the wall's: the same without the veil)
            albedos = np.array(display.surface_albedos) if display.surface_albedos else None
            bounce = self._bounce_images(sensor, surroundings).image(
                index, view, display.rig, display.medium, albedos
            )

        def through(medium: Medium) -> np.ma.MaskedArray:
            out = bounce + render_view_image(
                self.geo.render_camera,
                view,
                display.rig,
                port=self.project.camera_port,
                sensor=sensor,
                vignetting=self._vignetting,
                offset=0.0,
                rid_subsamples=self.project.solver.rid_subsamples,
                wall=display.wall,
                medium=medium,
                mesh=self.project.wall_mesh,
            )
            if sensor == "paper":
                # A binned pixel of `paper` is the mean of its b^2 pixels, not their sum.
                out = out / float(self.geo.render_binning**2)
            if display.ambient:  # the estimated room light, as the model adds it: through
                room = room_light_view(
                    self.geo.render_camera, sensor, self._vignetting, self.project.camera_port
                )
                level = view.exposure * display.ambient  # the sensor's fall-off (cos4, map)
                out = out + (level if room is None else level * room)
            if display.fall_off_coeffs:  # and the estimated fall-off at each super-pixel
                out = out * self._estimated_fall_off(display.fall_off_coeffs, out.shape)
            return out

        if display.albedo is None:
            return through(display.medium) + display.offset
        # and the wall's albedo where each one looks (not the water's veil)
        albedo = albedo_image(display.albedo, self.geo.render_camera, view)
        return with_albedo(through, display.medium, albedo) + display.offset

    def _estimated_fall_off(self, coeffs: tuple[float, ...], shape: tuple[int, ...]) -> np.ndarray:
        """(h, w) V of `coeffs` on the rendered (binned) grid (`FallOffUnknown`)."""
        from lightcal.core.fall_off import FallOffUnknown

        cam, b = self.geo.camera, self.geo.render_binning
        f = FallOffUnknown(len(coeffs), cam.width, cam.height, b)
        v, u = np.mgrid[0 : shape[0], 0 : shape[1]]
        pixels = np.stack([u.ravel(), v.ravel()], axis=1)
        return f.factor(pixels, np.array(coeffs)).reshape(shape)

    def residual(self, index: int, rendered: np.ma.MaskedArray) -> np.ma.MaskedArray:
        """(h, w) real minus rendered on the binned grid, masked where either is unknown."""
        real = self.real_binned[index]
        h, w = rendered.shape
        diff = real[:h, :w] - np.ma.filled(rendered.astype(np.float64), np.nan)
        return np.ma.masked_invalid(diff)

    def picture(
        self,
        index: int,
        kind: OverlayKind,
        *,
        rendered: np.ma.MaskedArray | None = None,
        residual_vmax: float = 1.0,
    ) -> np.ndarray:
        """(H_d, W_d, 3) uint8 picture of image `index` showing `kind`."""
        if kind == "real" or rendered is None:
            return self.real_rgb[index].copy()
        if kind == "rendered":
            return self._resize(grey_rgb(rendered, self.white[index]))
        res = self.residual(index, rendered)
        return self._resize(diverging_rgb(res, residual_vmax), nearest=True)

    def draw_selection(
        self,
        rgb: np.ndarray,
        index: int,
        *,
        selected: np.ndarray,
        binning: int,
        regions: tuple[UserRegion, ...],
        points: tuple[tuple[int, int], ...],
    ) -> np.ndarray:
        """Draw masks, regions, the selected pixels and clicked points on a picture.

        Args:
            rgb: (H_d, W_d, 3) picture (modified and returned).
            index: which image.
            selected: (N, 2) selected (super-)pixels in the grid binned by `binning`.
            binning: b of `selected`.
            regions: user regions that apply to this image.
            points: clicked full-resolution pixels.
        """
        geo = self.geo
        mask = self.mask_display[index]
        if mask.any():
            _blend_where(rgb, mask, self._mask_colour, 0.5)
        for r in regions:
            pts = np.array(r.points, dtype=np.float64)
            if r.kind == "rect":
                (u0, v0), (u1, v1) = pts
                pts = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
            d = np.round(full_to_display(pts, geo)).astype(np.int32)
            cv2.polylines(rgb, [d], True, INCLUDE_RGB if r.include else EXCLUDE_RGB, 2)
        if len(selected):
            d = np.round(full_to_display(binned_to_full(selected, binning), geo)).astype(int)
            d[:, 0] = np.clip(d[:, 0], 0, geo.width - 1)
            d[:, 1] = np.clip(d[:, 1], 0, geo.height - 1)
            marks = np.zeros((geo.height, geo.width), np.uint8)
            marks[d[:, 1], d[:, 0]] = 1
            cell = binning * geo.width / geo.camera.width  # a (super-)pixel, picture px
            radius = max(1, round(0.5 * cell))
            if len(selected) < 4000:
                radius = max(radius, 2)
            # At least a whole (super-)pixel: a dense binned selection's marks then touch,
            # and its outline is drawn (a 4 x 4 binned `all` covered half the picture
            # with a lattice of dots, hiding the residuals the albedo map flattens).
            side = max(2 * radius - 1, math.ceil(cell - 1e-9))
            kernel = np.ones((side, side), np.uint8)
            hit = cv2.dilate(marks, kernel)
            if hit.mean() > OUTLINE_FRACTION:
                # A dense selection (`all`, a fine grid) would paint the picture over:
                # its outline only, so that the residuals under it stay visible.
                inner = cv2.erode(hit, np.ones((5, 5), np.uint8), borderType=cv2.BORDER_REPLICATE)
                _blend_where(rgb, (hit > 0) & (inner == 0), self._selected_colour, 0.9)
            else:
                _blend_where(rgb, hit > 0, self._selected_colour, 0.65)
        for u, v in points:
            x, y = np.round(full_to_display(np.array([[u, v]]), geo)[0]).astype(int)
            cv2.drawMarker(rgb, (int(x), int(y)), POINT_RGB, cv2.MARKER_CROSS, 9, 2)
        return rgb


DIM_RGB = np.array([228, 226, 220], dtype=np.float64)
"""What a dimmed picture fades towards (the wall's grey)."""
DIM_KEEP = 0.35
"""How much of a dimmed picture stays."""


def dimmed(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 `rgb` faded towards the wall's grey (an image not highlighted)."""
    out = DIM_KEEP * rgb.astype(np.float64) + (1.0 - DIM_KEEP) * DIM_RGB
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def draw_name(rgb: np.ndarray, name: str) -> np.ndarray:
    """The image's name in its top-left corner, dark on a white box, about 12 % of the
    picture's height (in place, returned). On the picture itself, names of neighbouring
    cameras never overlap, as labels floating in the scene did."""
    h = rgb.shape[0]
    font = cv2.FONT_HERSHEY_SIMPLEX
    scale = max(0.4, 0.12 * h / 22.0)
    thickness = max(1, round(scale * 1.5))
    (tw, th), base = cv2.getTextSize(name, font, scale, thickness)
    pad = max(2, th // 3)
    cv2.rectangle(rgb, (0, 0), (tw + 2 * pad, th + base + 2 * pad), (255, 255, 255), -1)
    cv2.putText(rgb, name, (pad, pad + th), font, scale, (20, 20, 20), thickness, cv2.LINE_AA)
    return rgb


def _blend_where(rgb: np.ndarray, where: np.ndarray, colour: np.ndarray, alpha: float) -> None:
    """rgb = (1 - alpha) rgb + alpha colour where `where` (H, W) is True, in place."""
    mixed = cv2.addWeighted(rgb, 1.0 - alpha, colour, alpha, 0.0)
    cv2.copyTo(mixed, where.astype(np.uint8), rgb)  # ~20x faster than np.copyto(where=)


def shared_vmax(residuals: list[np.ma.MaskedArray]) -> float:
    """One colour scale for all residual maps: the 99th percentile of every |residual|."""
    parts = [np.ma.compressed(r) for r in residuals if r is not None]
    if not parts:
        return 1.0
    return robust_vmax(np.concatenate(parts))


def legend_picture(vmax: float, *, width: int = 320, height: int = 56) -> np.ndarray:
    """(height, width, 3) colour bar of the residual map with its scale (pixel values)."""
    img = np.full((height, width, 3), 255, np.uint8)
    pad = 14
    bar = np.linspace(-vmax, vmax, width - 2 * pad)[None, :].repeat(16, axis=0)
    img[6:22, pad : width - pad] = diverging_rgb(bar, vmax)
    font = cv2.FONT_HERSHEY_SIMPLEX
    v = f"{vmax:.4g}"
    for frac, text in ((0.0, f"-{v}"), (0.5, "0"), (1.0, f"+{v}")):
        x = pad + frac * (width - 2 * pad - 1)
        cv2.line(img, (int(x), 22), (int(x), 27), (20, 20, 20), 1)
        size = cv2.getTextSize(text, font, 0.42, 1)[0][0]
        x0 = int(np.clip(x - size / 2, 0, width - size))
        cv2.putText(img, text, (x0, 41), font, 0.42, (20, 20, 20), 1, cv2.LINE_AA)
    cv2.putText(img, "real - rendered", (pad, 54), font, 0.38, (90, 90, 90), 1, cv2.LINE_AA)
    return img
