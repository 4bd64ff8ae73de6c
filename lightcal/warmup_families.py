"""The kernel families `lightcal.warmup` compiles: one tiny synthetic calibration each,
whose argument types are those real projects give the kernels."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["DENSE", "FAMILIES", "Family"]


@dataclass(frozen=True)
class Family:
    """One group of kernels and the synthetic calibration that compiles it."""

    label: str
    size: tuple[int, int] = (64, 48)
    light_model: str = "cos_power"
    n_lights: int = 1
    wall: dict[str, Any] | None = None
    medium: dict[str, Any] | None = None
    selection: dict[str, Any] | None = None
    report: bool = False
    parallel: bool = False  # every flux call on the thread pool, however small
    noise_model: bool = True  # False: the noise estimated from the images (the sample's)
    synth: dict[str, Any] | None = None  # more of the dataset's `SynthConfig` fields


# Beyond the kinds of light and wall, numba compiles a kernel once per combination of
# argument types (read-only arrays count), and the large problems run parallel twins of
# the small ones' kernels: sparse and dense selections, small and large images, both.
_WATER = ["attenuation_per_m", "backscatter_per_m"]
DENSE = (200, 150)  # 30,000 pixels: above every kernel's parallel threshold (20,000)
FAMILIES: tuple[Family, ...] = (
    Family("sparse pixels, cos^m, solver"),
    Family(
        "all pixels, parallel kernels, report",
        size=DENSE,
        selection={"strategy": "all", "binning": 1},
        report=True,
        noise_model=False,
    ),
    # The parallel flux kernel on stored quads: what the intrinsics' uncertainty renders
    # (perturbed cameras) on a large project; here every flux call goes parallel.
    Family("binned pixels", size=DENSE, selection={"strategy": "all", "binning": 2}, parallel=True),
    Family("measured tables (IES, LDT, CSV)", light_model="ies"),
    Family("2-D tables, two lights", light_model="table2d", n_lights=2),
    Family("Gaussian lights", light_model="gaussian"),
    Family("isotropic lights", light_model="isotropic"),
    Family(
        "wall models: plastic",
        size=DENSE,
        wall={"model": "plastic", "estimate": ["roughness", "specular_weight"]},
        selection={"strategy": "all", "binning": 1},
    ),
    Family("wall models: Oren-Nayar", wall={"model": "oren_nayar", "estimate": ["sigma_deg"]}),
    Family(
        "water (the medium: per pixel, serial and parallel, and whole images)",
        size=DENSE,
        medium={"attenuation_per_m": 0.2, "backscatter_per_m": 0.3, "estimate": _WATER},
        selection={"strategy": "all", "binning": 1},
        report=True,
    ),
    # The ray-mesh intersection: footprints on a wall given as a mesh (here its plane).
    Family("a wall given as a mesh", synth={"declare_wall_mesh": True}),
    # The light's flat port: its path solve and flux, serial (the few pixels of a
    # perturbed solve) and parallel (all pixels, whole images), its water and its veil.
    Family(
        "a light behind a flat port (its path solve, water and veil)",
        size=DENSE,
        medium={"attenuation_per_m": 0.2, "backscatter_per_m": 0.3, "estimate": _WATER},
        selection={"strategy": "all", "binning": 1},
        report=True,
        synth={"light_port": (15.0, 8.0, 1.49, 1.333), "declare_light_port": True},
    ),
    # The camera's flat port: its footprints for the solver, and whole images through it
    # (the report's: the fused kernel on the port's corner lattice), in water.
    Family(
        "a camera behind a flat port (whole images through it)",
        medium={"attenuation_per_m": 0.2, "estimate": ["attenuation_per_m"]},
        report=True,
        synth={"port": (20.0, 10.0, 1.49, 1.333), "declare_port": True},
    ),
)
