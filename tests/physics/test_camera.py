"""The camera stage (murk.physics.camera, murk.synth CameraConfig/sample_camera): what each step does."""

from __future__ import annotations

import numpy as np
import pytest

from murk.physics.camera import apply_camera, jpeg_round_trip
from murk.synth.config import CameraConfig, SynthConfig
from murk.synth.params import CameraParams, sample_camera, sample_variant, variant_from_dict, variant_to_dict


def _params(**kw: object) -> CameraParams:
    base = {
        "wb_gains": (1.0, 1.0, 1.0),
        "exposure": 1.0,
        "read_noise": 0.0,
        "shot_noise": 0.0,
        "noise_seed": 1,
        "jpeg_quality": 0,
    }
    base.update(kw)
    return CameraParams(**base)  # type: ignore[arg-type]


def test_neutral_camera_only_quantises_to_8_bits() -> None:
    img = np.random.default_rng(0).random((20, 30, 3)).astype(np.float32)
    out = apply_camera(img, _params())
    np.testing.assert_array_equal(out, np.rint(img * 255).astype(np.uint8).astype(np.float32) * np.float32(1 / 255))
    assert out.dtype == np.float32


def test_gains_and_exposure_scale_each_channel_and_clip() -> None:
    img = np.full((8, 8, 3), 0.4, np.float32)
    out = apply_camera(img, _params(wb_gains=(1.5, 1.0, 0.5), exposure=2.0))
    np.testing.assert_allclose(out[0, 0], [1.0, 0.8, 0.4], atol=0.5 / 255)


def test_noise_has_the_modelled_standard_deviation_and_is_seeded() -> None:
    img = np.full((200, 200, 3), 0.5, np.float32)
    p = _params(read_noise=0.02, shot_noise=0.0008)  # sd = sqrt(0.0004 + 0.0004) = 0.0283
    out = apply_camera(img, p)
    assert abs(float(out.std()) - np.sqrt(0.0008)) < 0.002
    np.testing.assert_array_equal(out, apply_camera(img, p))
    assert not np.array_equal(out, apply_camera(img, _params(read_noise=0.02, shot_noise=0.0008, noise_seed=2)))


def test_jpeg_round_trip_loses_more_at_lower_quality() -> None:
    rng = np.random.default_rng(3)
    img = (rng.random((64, 64, 3)) * 255).astype(np.uint8)
    err = [np.abs(jpeg_round_trip(img, q).astype(float) - img).mean() for q in (95, 60)]
    assert 0 < err[0] < err[1]


def test_sampled_gains_have_geometric_mean_one_and_ranges_hold() -> None:
    cfg = CameraConfig()
    for seed in range(20):
        p = sample_camera(np.random.default_rng(seed), cfg)
        assert np.prod(p.wb_gains) == pytest.approx(1.0)
        assert cfg.exposure[0] <= p.exposure <= cfg.exposure[1]
        assert p.jpeg_quality == 0 or cfg.jpeg_quality[0] <= p.jpeg_quality <= cfg.jpeg_quality[1]
    never = CameraConfig(jpeg_probability=0.0)
    assert all(sample_camera(np.random.default_rng(s), never).jpeg_quality == 0 for s in range(10))


def test_camera_stage_round_trips_through_the_manifest_and_leaves_other_draws_alone() -> None:
    with_cam = sample_variant(np.random.default_rng(5), SynthConfig(stages=("basic", "forward_scatter", "camera")))
    without = sample_variant(np.random.default_rng(5), SynthConfig(stages=("basic", "forward_scatter")))
    assert with_cam.camera is not None and without.camera is None
    assert with_cam.medium == without.medium  # the camera draws come after the water's
    assert variant_from_dict(variant_to_dict(with_cam)) == with_cam


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"wb_sigma": -0.1}, "wb_sigma"),
        ({"exposure": (2.0, 1.0)}, "exposure"),
        ({"jpeg_quality": (0, 90)}, "jpeg_quality"),
        ({"jpeg_probability": 1.5}, "jpeg_probability"),
        ({"read_noise": (0.0, 2.0)}, "read_noise"),
    ],
)
def test_bad_camera_settings_are_refused_by_name(kw: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        CameraConfig(**kw)  # type: ignore[arg-type]
