"""The pinhole camera with OpenCV distortion.

Conventions (see docs/conventions.md): OpenCV camera frame (x right, y down, z forward);
pixel (u, v) = (column, row) has its centre at integer coordinates; intrinsics
K = [[fx, s, cx], [0, fy, cy], [0, 0, 1]]; distortion acts on normalised
coordinates (x/z, y/z) before K:

    (u, v) = (fx xd + s yd + cx, fy yd + cy),  (xd, yd) = distort(x/z, y/z)

Note that `cv2.projectPoints` ignores the skew s; with s = 0 the two agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.core.distortion import (
    ACCEPTED_DIST_LENGTHS,
    distort_points,
    pad_distortion,
    undistort_points,
)
from lightcal.errors import InputError


def _check_points(name: str, points: ArrayLike, n_cols: int) -> NDArray[np.float64]:
    """Return `points` as a float64 (N, n_cols) array or raise InputError."""
    array = np.asarray(points, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != n_cols:
        raise InputError(name, f"expected an (N, {n_cols}) array, got shape {array.shape}")
    return np.ascontiguousarray(array)


INTRINSIC_NAMES = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
"""Names of a camera's intrinsic parameters in `Camera.intrinsic_params` order."""


def _check_covariance(value: ArrayLike, p: int) -> NDArray[np.float64]:
    """`value` as a (p, p) symmetric, finite, positive semi-definite float64 copy."""
    name = "intrinsics_covariance"
    c = np.array(value, dtype=np.float64)
    if c.shape != (p, p):
        raise InputError(
            name, f"expected a {p}x{p} matrix (fx, fy, cx, cy, distortion), got shape {c.shape}"
        )
    if not np.all(np.isfinite(c)):
        raise InputError(name, "expected finite values, got NaN or infinity")
    scale = max(float(np.abs(c).max()), 1e-300)
    if not np.allclose(c, c.T, rtol=1e-6, atol=1e-12 * scale):
        raise InputError(name, "expected a symmetric matrix")
    d = np.sqrt(np.maximum(np.diag(c), 1e-300))
    if np.linalg.eigvalsh(0.5 * (c + c.T) / np.outer(d, d)).min() < -1e-9:
        raise InputError(name, "expected a positive semi-definite matrix")
    return 0.5 * (c + c.T)


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera with OpenCV distortion and a sensor size.

    Attributes:
        K: (3, 3) float64 intrinsics [[fx, s, cx], [0, fy, cy], [0, 0, 1]], in pixels.
        dist: (8,) float64 `(k1, k2, p1, p2, k3, k4, k5, k6)`, zero padded.
            The constructor also accepts 0, 4 or 5 coefficients and pads them.
        width: Image width in pixels (number of columns).
        height: Image height in pixels (number of rows).
        n_dist_coeffs: How many OpenCV coefficients the camera was given (0, 4, 5
            or 8), kept so that camera files round trip with the same vector
            length; the coefficients beyond it are zero. Defaults to the length
            of `dist` as passed to the constructor.
        intrinsics_covariance: (p, p) covariance of `intrinsic_params` (fx, fy, cx, cy
            and the `n_dist` coefficients, p = 4 + n_dist) from the calibration, or None
            (unknown). Symmetric, finite, positive semi-definite.

    The arrays are stored as read-only copies. Two cameras are equal when all
    fields are exactly equal.
    """

    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    width: int
    height: int
    n_dist_coeffs: int | None = None
    intrinsics_covariance: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        K = np.array(self.K, dtype=np.float64)
        if K.shape != (3, 3):
            raise InputError("K", f"expected a 3x3 matrix, got shape {K.shape}")
        if not np.all(np.isfinite(K)):
            raise InputError("K", "expected finite values, got NaN or infinity")
        if not (K[0, 0] > 0.0 and K[1, 1] > 0.0):
            raise InputError(
                "K", f"expected fx > 0 and fy > 0, got fx={float(K[0, 0])!r}, fy={float(K[1, 1])!r}"
            )
        if K[1, 0] != 0.0 or K[2, 0] != 0.0 or K[2, 1] != 0.0 or K[2, 2] != 1.0:
            raise InputError(
                "K",
                "expected the form [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got "
                f"K[1, 0]={float(K[1, 0])!r}, K[2, 0]={float(K[2, 0])!r}, "
                f"K[2, 1]={float(K[2, 1])!r}, K[2, 2]={float(K[2, 2])!r}",
            )

        raw = np.asarray(self.dist, dtype=np.float64)
        if raw.ndim > 1 and sum(1 for n in raw.shape if n != 1) > 1:
            raise InputError("dist", f"expected a vector of coefficients, got shape {raw.shape}")
        raw = raw.reshape(-1)
        if raw.size not in ACCEPTED_DIST_LENGTHS:
            raise InputError("dist", f"expected 0, 4, 5 or 8 coefficients, got {raw.size}")
        if not np.all(np.isfinite(raw)):
            raise InputError("dist", "expected finite values, got NaN or infinity")
        dist = pad_distortion(raw)
        n_dist = raw.size if self.n_dist_coeffs is None else self.n_dist_coeffs
        if isinstance(n_dist, bool) or not isinstance(n_dist, int | np.integer):
            raise InputError("n_dist_coeffs", f"expected an int, got {n_dist!r}")
        if n_dist not in ACCEPTED_DIST_LENGTHS:
            raise InputError("n_dist_coeffs", f"expected 0, 4, 5 or 8, got {n_dist}")
        if np.any(dist[n_dist:] != 0.0):
            raise InputError(
                "dist",
                f"expected zeros beyond the first n_dist_coeffs={n_dist} coefficients, "
                f"got {dist.tolist()}",
            )

        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value <= 0:
                raise InputError(name, f"expected a positive int, got {value!r}")
            object.__setattr__(self, name, int(value))

        K.flags.writeable = False
        dist.flags.writeable = False
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "dist", dist)
        object.__setattr__(self, "n_dist_coeffs", int(n_dist))
        if self.intrinsics_covariance is not None:
            cov = _check_covariance(self.intrinsics_covariance, 4 + int(n_dist))
            cov.flags.writeable = False
            object.__setattr__(self, "intrinsics_covariance", cov)

    @classmethod
    def from_params(
        cls,
        *,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        width: int,
        height: int,
        dist: ArrayLike = (),
        skew: float = 0.0,
    ) -> Camera:
        """Build a camera from its scalar intrinsics.

        Args:
            fx: Focal length along x, in pixels.
            fy: Focal length along y, in pixels.
            cx: Principal point column, in pixels (pixel centres at integers).
            cy: Principal point row, in pixels.
            width: Image width in pixels.
            height: Image height in pixels.
            dist: (n,) OpenCV coefficients, n in (0, 4, 5, 8).
            skew: K[0, 1], in pixels.
        """
        K = np.array([[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)
        return cls(K=K, dist=np.asarray(dist, dtype=np.float64), width=width, height=height)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Camera):
            return NotImplemented
        return (
            np.array_equal(self.K, other.K)
            and np.array_equal(self.dist, other.dist)
            and self.width == other.width
            and self.height == other.height
            and self.n_dist_coeffs == other.n_dist_coeffs
            and (
                (self.intrinsics_covariance is None and other.intrinsics_covariance is None)
                or (
                    self.intrinsics_covariance is not None
                    and other.intrinsics_covariance is not None
                    and np.array_equal(self.intrinsics_covariance, other.intrinsics_covariance)
                )
            )
        )

    __hash__: Any = None

    def __repr__(self) -> str:
        return (
            f"Camera(fx={self.fx!r}, fy={self.fy!r}, cx={self.cx!r}, cy={self.cy!r}, "
            f"skew={self.skew!r}, dist={self.dist[: self.n_dist].tolist()!r}, "
            f"width={self.width}, height={self.height})"
        )

    @property
    def fx(self) -> float:
        """Focal length along x, in pixels."""
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        """Focal length along y, in pixels."""
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        """Principal point column, in pixels."""
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        """Principal point row, in pixels."""
        return float(self.K[1, 2])

    @property
    def skew(self) -> float:
        """Skew K[0, 1], in pixels."""
        return float(self.K[0, 1])

    @property
    def n_dist(self) -> int:
        """Number of meaningful distortion coefficients (0, 4, 5 or 8)."""
        assert self.n_dist_coeffs is not None  # set by __post_init__
        return self.n_dist_coeffs

    @property
    def dist_opencv(self) -> NDArray[np.float64]:
        """(n_dist,) the distortion vector as OpenCV functions take it."""
        return self.dist[: self.n_dist].copy()

    @property
    def intrinsic_names(self) -> tuple[str, ...]:
        """Names of `intrinsic_params`: fx, fy, cx, cy, then k1, k2, p1, p2, k3, k4, k5, k6
        up to `n_dist` coefficients."""
        return INTRINSIC_NAMES[: 4 + self.n_dist]

    @property
    def intrinsic_params(self) -> NDArray[np.float64]:
        """(4 + n_dist,) (fx, fy, cx, cy, the distortion coefficients): what
        `intrinsics_covariance` is the covariance of."""
        return np.concatenate([[self.fx, self.fy, self.cx, self.cy], self.dist[: self.n_dist]])

    def with_intrinsic_params(self, params: ArrayLike) -> Camera:
        """The camera with `intrinsic_params` replaced (skew, size and covariance kept).

        Args:
            params: (4 + n_dist,) fx, fy, cx, cy and the distortion coefficients.
        """
        p = np.asarray(params, dtype=np.float64).reshape(-1)
        if p.size != 4 + self.n_dist:
            raise InputError(
                "params", f"expected {4 + self.n_dist} intrinsic parameters, got {p.size}"
            )
        K = self.K.copy()
        K[0, 0], K[1, 1], K[0, 2], K[1, 2] = p[:4]
        camera = Camera(
            K=K, dist=p[4:].copy(), width=self.width, height=self.height, n_dist_coeffs=self.n_dist
        )
        # This camera's covariance, checked when it was made (its eigenvalues cost more
        # than the rest of a camera: the uncertainty renders make hundreds of these).
        object.__setattr__(camera, "intrinsics_covariance", self.intrinsics_covariance)
        return camera

    @property
    def fov_y_rad(self) -> float:
        """Vertical field of view of the undistorted pinhole, 2 atan(H / (2 fy))."""
        return 2.0 * math.atan(self.height / (2.0 * self.fy))

    @property
    def aspect(self) -> float:
        """Image aspect ratio width / height."""
        return self.width / self.height

    def project(self, points_camera: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Project points given in the camera frame to pixels (with distortion).

        Args:
            points_camera: (N, 3) points in the camera frame, metres.

        Returns:
            pixels: (N, 2) (u, v), NaN where not valid.
            valid: (N,) True where the point is finite and in front (z > 0).
        """
        points = _check_points("points_camera", points_camera, 3)
        valid = np.all(np.isfinite(points), axis=1) & (points[:, 2] > 0.0)
        xy = np.full((points.shape[0], 2), np.nan)
        xy[valid] = points[valid, :2] / points[valid, 2:3]
        pixels = self.normalized_to_pixels(xy)
        pixels[~valid] = np.nan
        return pixels, valid

    def normalized_to_pixels(self, xy: ArrayLike) -> NDArray[np.float64]:
        """Distort normalised coordinates and apply K.

        Args:
            xy: (N, 2) undistorted normalised coordinates (x/z, y/z).

        Returns:
            pixels: (N, 2) (u, v).
        """
        points = _check_points("xy", xy, 2)
        xy_distorted = distort_points(points, self.dist)
        K = self.K
        u = K[0, 0] * xy_distorted[:, 0] + K[0, 1] * xy_distorted[:, 1] + K[0, 2]
        v = K[1, 1] * xy_distorted[:, 1] + K[1, 2]
        return np.stack([u, v], axis=1)

    def pixels_to_normalized(
        self, pixels: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Undo K and the distortion.

        Args:
            pixels: (N, 2) (u, v) pixel coordinates.

        Returns:
            xy: (N, 2) undistorted normalised coordinates (x/z, y/z), NaN where
                not valid.
            valid: (N,) False where a pixel is not finite or lies outside the
                distortion model's valid region (see `undistort_normalized`).
        """
        points = _check_points("pixels", pixels, 2)
        K = self.K
        yd = (points[:, 1] - K[1, 2]) / K[1, 1]
        xd = (points[:, 0] - K[0, 2] - K[0, 1] * yd) / K[0, 0]
        xy, valid = undistort_points(np.stack([xd, yd], axis=1), self.dist)
        return xy, valid

    def rays_camera(self, pixels: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Back-project pixels to rays in the camera frame.

        Args:
            pixels: (N, 2) (u, v) pixel coordinates.

        Returns:
            rays: (N, 3) (x, y, 1): not unit length, z = 1; NaN rows where not valid.
            valid: (N,) as in `pixels_to_normalized`.
        """
        xy, valid = self.pixels_to_normalized(pixels)
        rays = np.empty((xy.shape[0], 3))
        rays[:, :2] = xy
        rays[:, 2] = np.where(valid, 1.0, np.nan)
        return rays, valid

    def binned(self, b: int) -> Camera:
        """The camera of the same sensor read out with b x b binning.

        With pixel centres at integers, full-resolution pixel p maps to binned
        coordinate (p + 0.5) / b - 0.5 (binned pixel 0 covers full pixels 0..b-1,
        whose centre is (b - 1) / 2). Hence fx' = fx / b, fy' = fy / b,
        s' = s / b, cx' = (cx + 0.5) / b - 0.5, cy' = (cy + 0.5) / b - 0.5; the
        distortion (on normalised coordinates) is unchanged; the size is
        width // b x height // b (a partial bin at the edge is dropped).

        Args:
            b: Binning factor, a positive int (1 returns an equal camera).

        Returns:
            The binned camera.
        """
        if isinstance(b, bool) or not isinstance(b, int | np.integer) or b <= 0:
            raise InputError("b", f"expected a positive int binning factor, got {b!r}")
        if self.width // b == 0 or self.height // b == 0:
            raise InputError(
                "b",
                f"expected a binning factor <= min(width, height) = "
                f"{min(self.width, self.height)}, got {b}",
            )
        K = self.K.copy()
        K[0, 0] /= b
        K[0, 1] /= b
        K[1, 1] /= b
        K[0, 2] = (K[0, 2] + 0.5) / b - 0.5
        K[1, 2] = (K[1, 2] + 0.5) / b - 0.5
        cov = self.intrinsics_covariance
        if cov is not None:
            # fx, fy, cx, cy scale by 1 / b (cx, cy up to a constant); distortion does not.
            scale = np.concatenate([np.full(4, 1.0 / b), np.ones(self.n_dist)])
            cov = cov * np.outer(scale, scale)
        return Camera(
            K=K,
            dist=self.dist.copy(),
            width=self.width // b,
            height=self.height // b,
            n_dist_coeffs=self.n_dist,
            intrinsics_covariance=cov,
        )
