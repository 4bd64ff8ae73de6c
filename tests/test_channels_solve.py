"""Colour channels solved jointly: one light pose, each channel its own scale, room
light and water (`ParameterLayout`'s channels, `ImageData.channel`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from lightcal.core.medium import Medium
from lightcal.core.problem import LightUnknown, MediumUnknown, ParameterLayout
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares
from tests.calib_scenes import (
    assert_columns_match_differences,
    observe,
    pose_errors,
    small_camera,
    start_near,
    symmetric_light,
    views,
)

CHANNELS = ("R", "G", "B")
C_TRUE = (0.45, 0.12, 0.06)  # ocean water: red absorbed most
SCALE_RATIO = (0.8, 1.0, 0.6)  # the wall's colour times the light's


def _channel_images(*, noise=None, seed: int = 3, n_views: int = 8):
    """Per channel the same views' pixels through that channel's water and scale."""
    camera = small_camera()
    vs = views(n_views, seed=seed)
    truth = symmetric_light()
    images = []
    for ch, (c, ratio) in enumerate(zip(C_TRUE, SCALE_RATIO, strict=True)):
        light = replace(truth, scale=truth.scale * ratio)
        seen = observe(
            camera,
            vs,
            Rig.single(light),
            rng=np.random.default_rng(seed + ch),
            medium=Medium(c),
            noise=noise,
            noise_model=noise is not None,
        )
        images += [replace(im, name=f"{im.name}[{CHANNELS[ch]}]", channel=ch) for im in seen]
    return images, truth


def _joint_model(images, truth, options=None):
    media = tuple(MediumUnknown(Medium(0.2), ("attenuation_per_m",)) for _ in CHANNELS)
    return CalibrationModel(
        images,
        [LightUnknown(start_near(truth))],
        options or SolverOptions(),
        channels=CHANNELS,
        media=media,
    )


def test_layout_gives_each_channel_its_scales_room_light_and_medium() -> None:
    truth = symmetric_light()
    media = [MediumUnknown(Medium(c), ("attenuation_per_m", "backscatter_per_m")) for c in C_TRUE]
    lay = ParameterLayout.build(
        [LightUnknown(truth)],
        4,
        estimate_gains=False,
        estimate_offset=False,
        offset0=0.0,
        estimate_ambient=True,
        channels=CHANNELS,
        media=media,
    )
    name = truth.name
    assert lay.names[-10:] == [
        f"{name}.log_scale.B",
        "ambient.R",
        "ambient.G",
        "ambient.B",
        "medium.R.attenuation_per_m",
        "medium.R.backscatter_per_m",
        "medium.G.attenuation_per_m",
        "medium.G.backscatter_per_m",
        "medium.B.attenuation_per_m",
        "medium.B.backscatter_per_m",
    ]
    assert [lay.names[k] for k in lay.blocks[0].log_scales] == [
        f"{name}.log_scale.{ch}" for ch in CHANNELS
    ]
    assert lay.names[lay.medium] == [
        f"medium.{ch}.{nm}" for ch in CHANNELS for nm in ("attenuation_per_m", "backscatter_per_m")
    ]
    x = lay.x0.copy()
    x[lay.medium_columns(2)] = [0.3, 4.0]
    x[lay.ambient_indices[1]] = 7.0
    x[lay.blocks[0].log_scales[1]] = np.log(5.0)
    assert lay.medium_of(x, 2) == Medium(0.3, 4.0, 0.9)
    assert lay.medium_of(x, 0).attenuation_per_m == C_TRUE[0]
    assert lay.ambient(x, 1) == 7.0 and lay.ambient(x, 0) == 0.0
    assert lay.rig(x, 1).lights[0].scale == pytest.approx(5.0)
    assert lay.rig(x, 0).lights[0].scale == pytest.approx(truth.scale)
    lo, hi = lay.medium_bounds()
    assert lo.shape == hi.shape == (6,)


@pytest.mark.parametrize(
    ("channels", "media", "message"),
    [
        (("R",), None, "channels: expected 2 or more distinct names, got ['R']"),
        (("R", "R"), None, "channels: expected 2 or more distinct names, got ['R', 'R']"),
        (("R", "G"), [MediumUnknown()], "medium: expected one per channel (2), got 1"),
        (
            ("R", "G"),
            [MediumUnknown(), MediumUnknown(Medium(0.1), ("attenuation_per_m",))],
            "medium: expected every channel to estimate the same parameters",
        ),
    ],
)
def test_layout_refuses_bad_channels(channels, media, message) -> None:
    with pytest.raises(ValueError) as err:
        ParameterLayout.build(
            [LightUnknown(symmetric_light())],
            2,
            estimate_gains=False,
            estimate_offset=False,
            offset0=0.0,
            channels=channels,
            media=media,
        )
    assert str(err.value) == message


def test_image_of_a_channel_the_layout_lacks_is_refused() -> None:
    images, truth = _channel_images(n_views=2)
    with pytest.raises(ValueError, match=r"channel 2: expected an index below 2"):
        CalibrationModel(
            images,
            [LightUnknown(truth)],
            SolverOptions(),
            channels=("R", "G"),
        )


def test_joint_jacobian_matches_differences() -> None:
    """Every column (pose, each channel's scale, room light and c) against central
    differences; an image's columns of other channels are 0."""
    images, truth = _channel_images(n_views=2)
    model = _joint_model(images, truth, SolverOptions(estimate_ambient=True))
    lay = model.layout
    x = lay.x0.copy()
    x[lay.medium] = [0.3, 0.1, 0.05]
    x[lay.ambient_indices[0] : lay.ambient_indices[-1] + 1] = [1e-3, 2e-3, 3e-3]
    J = assert_columns_match_differences(model, x)
    for i, im in enumerate(images):
        rows = slice(model.bounds[i], model.bounds[i + 1])
        other = [ch for ch in range(3) if ch != im.channel]
        cols = [lay.blocks[0].log_scales[ch] for ch in other] + [
            lay.medium_columns(ch).start for ch in other
        ]
        assert np.all(J[rows][:, cols] == 0.0)


def test_noise_free_channels_recover_one_pose_and_each_c() -> None:
    """Noise-free, from a start 5 cm / 5 deg off and c = 0.2 in every channel: the pose to
    1e-6 m, each channel's c to 1e-6 /m and its scale ratio to 1e-6."""
    images, truth = _channel_images()
    model = _joint_model(images, truth)
    out = run_least_squares(model)
    assert out.success, out.message
    lay = model.layout
    dp, da = pose_errors(lay.rig(out.x).lights[0], truth)
    assert dp < 1e-6 and da < 1e-4
    for ch, (c, ratio) in enumerate(zip(C_TRUE, SCALE_RATIO, strict=True)):
        assert lay.medium_of(out.x, ch).attenuation_per_m == pytest.approx(c, abs=1e-6)
        scale = lay.rig(out.x, ch).lights[0].scale
        assert scale == pytest.approx(truth.scale * ratio, rel=1e-6)


def test_joint_pose_is_tighter_than_one_channel_alone() -> None:
    """With sensor noise the three channels' joint pose has a smaller sigma than the
    green channel's own calibration (more pixels on one pose)."""
    images, truth = _channel_images(noise=(0.5, 4.0))
    joint = _joint_model(images, truth)
    out = run_least_squares(joint)
    green = [replace(im, channel=0) for im in images if im.channel == 1]
    alone = CalibrationModel(
        green,
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        medium=MediumUnknown(Medium(0.2), ("attenuation_per_m",)),
    )
    out_alone = run_least_squares(alone)
    pose = joint.layout.blocks[0].pose
    sd_joint = np.sqrt(np.diag(np.linalg.inv(joint.normal_matrix(out.x)))[pose][:3])
    sd_alone = np.sqrt(np.diag(np.linalg.inv(alone.normal_matrix(out_alone.x)))[pose][:3])
    assert np.all(sd_joint < 0.8 * sd_alone), (sd_joint, sd_alone)
    dp, _ = pose_errors(joint.layout.rig(out.x).lights[0], truth)
    assert dp < 4 * np.linalg.norm(sd_joint)


def test_page_display_renders_each_channel_with_its_own() -> None:
    """The page's estimate display holds every channel's lights, medium and room light;
    an image's overlay takes its channel's (`Display.of_channel`)."""
    from lightcal_app.solve_display import estimate_display

    images, truth = _channel_images(n_views=2)
    model = _joint_model(images, truth)
    lay = model.layout
    x = lay.x0.copy()
    x[lay.medium] = [0.4, 0.1, 0.05]
    x[list(lay.blocks[0].log_scales)] = np.log([2.0, 3.0, 4.0])
    display = estimate_display(
        model,
        x,
        n_images=len(images),
        model_index=range(len(images)),
        setup_rev=0,
        fall_off="radiance",
    )
    for ch, (c, s) in enumerate(zip((0.4, 0.1, 0.05), (2.0, 3.0, 4.0), strict=True)):
        shown = display.of_channel(ch)
        assert shown.medium.attenuation_per_m == c
        assert shown.rig.lights[0].scale == pytest.approx(s)
    assert display.medium.attenuation_per_m == 0.4


def test_a_photos_channels_share_one_pose_error() -> None:
    """Blocks of one pose (a photo's channels) add G C G^T of their summed sensitivity:
    two blocks of pose 0 are the one block of their rows stacked, and twice as much as
    two independent poses for equal blocks (errors add in amplitude, not in variance)."""
    from lightcal.core.uncertainty import PoseBlock, pose_terms

    rng = np.random.default_rng(0)
    n, k = 4, 30
    A = rng.normal(size=(2 * k, n))
    N_inv = np.linalg.inv(A.T @ A)
    J, S = rng.normal(size=(k, n)), rng.normal(size=(k, 6))
    C = np.diag(rng.uniform(0.5, 2.0, size=6))
    ratio = np.ones(k)
    shared = pose_terms(
        N_inv, [PoseBlock(J, S, C, ratio, 1.0, 0), PoseBlock(J, S, C, ratio, 1.0, 0)]
    )
    stacked = pose_terms(
        N_inv, [PoseBlock(np.vstack([J, J]), np.vstack([S, S]), C, np.ones(2 * k), 1.0)]
    )
    np.testing.assert_allclose(shared.covariance, stacked.covariance, rtol=1e-12)
    assert shared.expected_chi2_extra == pytest.approx(stacked.expected_chi2_extra, rel=1e-12)
    assert shared.images == stacked.images == 1
    apart = pose_terms(N_inv, [PoseBlock(J, S, C, ratio), PoseBlock(J, S, C, ratio)])
    assert apart.images == 2
    np.testing.assert_allclose(shared.covariance, 2.0 * apart.covariance, rtol=1e-12)
