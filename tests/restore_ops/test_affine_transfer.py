"""The locally affine transfer of a restoration onto its input (murk.restore_ops.affine_transfer)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from murk.restore_ops.affine_transfer import affine_transfer, guard_particle_removal, guard_size_px, transfer_radius_px


def _textured(h: int = 60, w: int = 80, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    smooth = cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 3)
    return np.clip(0.2 + 0.6 * smooth / smooth.max() + 0.05 * rng.random((h, w, 3)), 0, 1).astype(np.float32)


def test_a_per_channel_affine_restoration_is_reproduced_exactly() -> None:
    # Eq. (1) inverted at one distance: J_c = a_c I_c + b_c. The fit finds it in every window, borders included.
    img = _textured()
    restored = img * np.array([1.8, 1.3, 0.9], np.float32) + np.array([-0.25, -0.1, 0.05], np.float32)
    out = affine_transfer(img, restored, radius_px=4, eps=1e-9)
    np.testing.assert_allclose(out, restored, atol=2e-3)


def test_what_is_not_affine_in_the_input_is_dropped() -> None:
    # A restoration that also removes a bright particle: the transfer keeps the colour change and brings the
    # particle back (the trade-off in docs/enhance.md), while the input's own structure passes through.
    img = _textured()
    img[30, 40] = 1.0  # a particle in the input
    restored = 0.5 * img + 0.1
    restored[30, 40] = restored[29, 40]  # the restoration took it out
    out = affine_transfer(img, restored, radius_px=8, eps=1e-6)
    particle = out[30, 40] - out[29, 40]
    assert np.all(particle > 0.6 * 0.5 * (img[30, 40] - img[29, 40]))  # most of the particle's contrast is back
    away = (slice(0, 20), slice(0, 30))
    np.testing.assert_allclose(out[away], (0.5 * img + 0.1)[away], atol=3e-3)


def test_radius_is_a_fraction_of_the_long_side_kept_inside_the_image() -> None:
    assert transfer_radius_px(480, 640, 0.125) == 80
    assert transfer_radius_px(256, 192, 0.125) == 32
    assert transfer_radius_px(10, 200, 0.5) == 9  # below the short side, for the reflected border
    assert transfer_radius_px(40, 40, 0.001) == 1


def test_bad_arguments_are_named_by_both_twins() -> None:
    import torch

    from murk.restore_ops.affine_transfer import affine_transfer_torch, guard_particle_removal_torch

    img = _textured()  # 60 x 80
    t = torch.from_numpy(img).permute(2, 0, 1)[None]
    cases = [
        ("image/restored: expected two", (img, img[:, :-1], 2), {}),
        (r"radius_px: expected an integer from 1 to the short side \(60\)", (img, img, 0), {}),
        (r"radius_px: expected an integer from 1 to the short side \(60\)", (img, img, 61), {}),
        ("eps: expected > 0", (img, img, 2), {"eps": 0.0}),
        ("step: expected an odd integer >= 1", (img, img, 2), {"step": 2}),
        ("step: expected an odd integer >= 1 whose centre sample lies in the frame", (img, img, 40), {"step": 121}),
    ]
    for match, (a, b, r), kw in cases:
        with pytest.raises(ValueError, match=match):
            affine_transfer(a, b, r, **kw)
        ta, tb = (torch.from_numpy(np.ascontiguousarray(x)).permute(2, 0, 1)[None] for x in (a, b))
        with pytest.raises(ValueError, match=match):
            affine_transfer_torch(ta, tb, r, **kw)
    assert affine_transfer(img, img, 60).shape == img.shape  # the short side itself is allowed
    assert affine_transfer_torch(t, t, 60).shape == t.shape
    with pytest.raises(ValueError, match=r"image/transfer/restored: expected three \(B, 3, H, W\) batches"):
        guard_particle_removal_torch(t, t, t[..., :-1], 0.04, 5)
    with pytest.raises(ValueError, match="threshold: expected a top-hat luma > 0"):
        guard_particle_removal_torch(t, t, t, 0.0, 5)
    with pytest.raises(ValueError, match="size_px: expected an odd integer >= 3"):
        guard_particle_removal_torch(t, t, t, 0.04, 4)


def test_the_guard_keeps_the_restorations_particle_removal_and_nothing_else() -> None:
    # The restoration takes a 3x3 particle out of the input and darkens a large patch. The transfer brings the
    # particle back; the guard keeps the restoration there. The large patch is no particle: the transfer stays.
    img = cv2.GaussianBlur(_textured(), (0, 0), 2)  # smooth: no particle-like texture of its own
    img[29:32, 39:42] = np.minimum(img[29:32, 39:42] + 0.4, 1.0)  # a particle in the input
    restored = 0.5 * img + 0.1
    restored[29:32, 39:42] = restored[26:29, 39:42]  # the restoration took it out
    restored[2:22, 2:32] -= 0.1  # and darkened a large patch
    transfer = affine_transfer(img, restored, radius_px=8, eps=1e-6)
    out = guard_particle_removal(img, transfer, restored, threshold=0.04, size_px=7)  # larger than the particle
    p = (slice(29, 32), slice(39, 42))
    assert np.all(transfer[30, 40] - restored[30, 40] > 0.01)  # without the guard the particle was back
    np.testing.assert_allclose(out[30, 40], restored[30, 40], atol=1e-6)  # with it, removed at the centre
    assert np.all(np.abs(out[p] - restored[p]) <= 0.25 * np.abs(transfer[p] - restored[p]) + 1e-6)  # and mostly
    assert np.abs(transfer[5:19, 5:29] - restored[5:19, 5:29]).max() > 0.01  # the patch differs, and
    np.testing.assert_array_equal(out[:25, :35], transfer[:25, :35])  # the guard leaves it to the transfer
    # A bright blob the restoration kept is left to the transfer (the second test fails).
    np.testing.assert_allclose(guard_particle_removal(img, transfer, transfer, 0.04, 7), transfer, atol=1e-7)


def test_guard_size_and_errors() -> None:
    assert guard_size_px(480, 640) == 27 and guard_size_px(240, 320) == 13 and guard_size_px(10, 20) == 3
    img = _textured()
    with pytest.raises(ValueError, match="image/transfer/restored: expected three"):
        guard_particle_removal(img, img, img[:, :-1], 0.04, 5)
    with pytest.raises(ValueError, match="threshold: expected a top-hat luma > 0"):
        guard_particle_removal(img, img, img, 0.0, 5)
    for bad in (2, 4):
        with pytest.raises(ValueError, match="size_px: expected an odd integer >= 3"):
            guard_particle_removal(img, img, img, 0.04, bad)


@pytest.mark.parametrize("hw", [(1, 1), (2, 3), (3, 200), (1, 50), (33, 31)])
def test_any_frame_size_works_and_the_twins_agree(hw: tuple[int, int]) -> None:
    import torch

    from murk.restore_ops.affine_transfer import affine_transfer_torch, guard_particle_removal_torch

    rng = np.random.default_rng(sum(hw))
    img = rng.random((*hw, 3)).astype(np.float32)
    res = np.clip(1.3 * img - 0.1 + 0.05 * rng.standard_normal(img.shape), 0, 1).astype(np.float32)
    radius, size = transfer_radius_px(*hw, 0.125), guard_size_px(*hw)
    out = guard_particle_removal(img, affine_transfer(img, res, radius), res, 0.04, size)
    assert out.shape == img.shape and np.isfinite(out).all()
    t_img, t_res = (torch.from_numpy(a).permute(2, 0, 1)[None] for a in (img, res))
    twin = guard_particle_removal_torch(t_img, affine_transfer_torch(t_img, t_res, radius), t_res, 0.04, size)
    np.testing.assert_allclose(twin[0].permute(1, 2, 0).numpy(), out, atol=1e-6)


def test_the_fast_guided_filter_step_rule_and_how_close_it_stays() -> None:
    from murk.restore_ops.affine_transfer import transfer_step

    assert [transfer_step(r) for r in (1, 15, 16, 24, 32, 40, 80)] == [1, 1, 1, 3, 3, 5, 9]
    # Eq. (1) inverted exactly: the subsampled fit finds the same map.
    img = _textured(120, 160)
    restored = img * np.array([1.8, 1.3, 0.9], np.float32) + np.array([-0.25, -0.1, 0.05], np.float32)
    np.testing.assert_allclose(affine_transfer(img, restored, 24, 1e-9, step=3), restored, atol=3e-3)
    # A restoration that is not affine in the input: the fast filter stays close to the exact one.
    rng = np.random.default_rng(1)
    other = np.clip(cv2.GaussianBlur(restored, (0, 0), 2) + 0.05 * rng.standard_normal(img.shape), 0, 1)
    exact = affine_transfer(img, other.astype(np.float32), 24)
    fast = affine_transfer(img, other.astype(np.float32), 24, step=3)
    assert np.abs(fast - exact).mean() < 3e-3
    with pytest.raises(ValueError, match="step: expected an odd integer >= 1"):
        affine_transfer(img, restored, 24, step=2)
