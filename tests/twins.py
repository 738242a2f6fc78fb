"""The numpy/torch twins of murk and the ONE table of tolerances they are held to (DESIGN rule 8).

Every operation that exists as a numpy/OpenCV function and a torch function has an entry here: how to make its
inputs, how to run each twin on them (numpy one image at a time, torch on the whole batch: batching must not
couple images), and the tolerance (``atol``, ``rtol`` of ``np.testing.assert_allclose``; 0/0 = bit-identical).
``tests/test_twins.py`` runs every entry. Tolerances are what float32 arithmetic in a different order allows
(about 1e-6 on [0, 1] images); metrics computed in float64 are held to 1e-9 or tighter, except UIQM's
components, whose torch twin sums in float32 (measured worst cases: UICM 1e-4, UISM 1e-5, UIConM 1e-6 relative).
A tolerance is loosened here, in one reviewed place, or not at all.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

Arrays = dict[str, np.ndarray]


@dataclass(frozen=True)
class Twin:
    """A numpy/torch pair: ``inputs(rng)`` -> arrays; each twin maps them to named output arrays."""

    inputs: Callable[[np.random.Generator], Arrays]
    numpy: Callable[[Arrays], Arrays]
    torch: Callable[[Arrays], Arrays]
    atol: float
    rtol: float = 0.0


def nchw(a: np.ndarray) -> torch.Tensor:
    """(B, H, W, C) numpy -> (B, C, H, W) torch (shared memory)."""
    return torch.from_numpy(np.ascontiguousarray(a)).permute(0, 3, 1, 2)


def nhwc(t: torch.Tensor) -> np.ndarray:
    """(B, C, H, W) torch -> (B, H, W, C) numpy."""
    return t.detach().permute(0, 2, 3, 1).cpu().numpy()


def per_image(fn: Callable[..., np.ndarray], *names: str) -> Callable[[Arrays], Arrays]:
    """The numpy twin applied image by image to the named batched inputs, stacked as output ``out``."""
    return lambda x: {"out": np.stack([fn(*(x[n][i] for n in names)) for i in range(len(x[names[0]]))])}


# --- inputs ------------------------------------------------------------------------------------------------------


def _images(b: int, h: int, w: int) -> Callable[[np.random.Generator], Arrays]:
    return lambda rng: {"images": rng.random((b, h, w, 3)).astype(np.float32)}


def _murky(rng: np.random.Generator) -> Arrays:
    """Smooth, low-contrast images (like murky water), each with its own histogram."""
    import cv2

    out = []
    for _ in range(3):
        img = cv2.GaussianBlur(rng.random((45, 67, 3)).astype(np.float32), (0, 0), 2.0)
        img = (img - img.min()) / (img.max() - img.min())
        out.append((0.1 + 0.6 * img).astype(np.float32))
    return {"images": np.stack(out)}


def _medium_inputs(rng: np.random.Generator) -> Arrays:
    from murk.physics.jerlov import beta_per_m
    from murk.physics.medium import ambient_light, distance_map

    depth = (rng.random((2, 7, 9)) * 8 + 0.5).astype(np.float32)
    near, far = np.array([0.3, 0.3]), np.array([12.0, 3.5])
    return {
        "images": rng.random((2, 7, 9, 3)).astype(np.float32),
        "depth": depth,
        "near": near,
        "far": far,
        "dist": np.stack([distance_map(depth[i], near_m=near[i], far_m=far[i]) for i in range(2)]),
        "beta": np.stack([beta_per_m("IB"), beta_per_m("7C")]),
        "b_inf": np.stack([ambient_light("IB", 3.2), ambient_light("7C", 4.8)]),
    }


def _scatter_inputs(rng: np.random.Generator) -> Arrays:
    yy, xx = np.mgrid[0:20, 0:24].astype(np.float32)
    ramp = 0.5 + 7.5 * (xx + yy) / (19 + 23)
    return {
        "images": rng.random((2, 20, 24, 3)).astype(np.float32),
        "dist": np.stack([ramp, ramp[:, ::-1] * 0.5 + 0.2]).astype(np.float32),
    }


def _pairs(b: int, h: int, w: int, noise: float) -> Callable[[np.random.Generator], Arrays]:
    def make(rng: np.random.Generator) -> Arrays:
        ref = rng.random((b, h, w, 3))
        pred = np.clip(ref + noise * rng.standard_normal(ref.shape), 0.0, 1.0)
        pred[1] = ref[1]  # identical images: PSNR inf, SSIM 1
        return {"pred": pred, "ref": ref}

    return make


def _depth_inputs(rng: np.random.Generator) -> Arrays:
    gt = rng.uniform(0.3, 14.0, (3, 12, 16))
    pred = gt * rng.uniform(0.7, 1.4, gt.shape)
    gt[0, :2] = 0.0  # invalid rows
    pred[1, 0, :3] = (np.nan, 100.0, -1.0)
    return {"pred": pred, "gt": gt}


def _transfer_inputs(rng: np.random.Generator) -> Arrays:
    """Textured inputs with particles, and a restoration that is a smooth colour map plus its own texture with the
    particles taken out (what the affine transfer and its guard see)."""
    import cv2

    b, h, w = 2, 41, 57
    images = np.stack([cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 1.5) for _ in range(b)])
    images = 0.15 + 0.7 * (images - images.min()) / (images.max() - images.min())
    restored = np.clip(1.4 * images - 0.1 + 0.03 * rng.standard_normal(images.shape), 0, 1).astype(np.float32)
    for i in range(b):
        for y, x in rng.integers(3, (h - 3, w - 3), (6, 2)):
            images[i, y - 1 : y + 2, x - 1 : x + 2] += 0.3
    images = np.clip(images, 0, 1).astype(np.float32)
    return {"images": images, "restored": restored}


_IR = ("images", "restored")


def _flat_in_batch(rng: np.random.Generator) -> Arrays:
    images = rng.random((3, 17, 29, 3)).astype(np.float32)
    images[1] = 0.4  # a flat image in the batch
    return {"images": images}


# --- the table ---------------------------------------------------------------------------------------------------


def _water_inputs(rng: np.random.Generator) -> Arrays:
    images = rng.uniform(0.0, 1.0, (2, 12, 16, 3)).astype(np.float32)
    dist = rng.uniform(0.3, 12.0, (2, 12, 16)).astype(np.float32)
    veil = rng.uniform(0.05, 1.2, (2, 3)).astype(np.float32)
    att = rng.uniform(0.01, 0.8, (2, 3)).astype(np.float32)
    return {"images": images, "dist": dist, "veil": veil, "att": att}


def _table() -> dict[str, Twin]:
    from murk.enhance import equalize as eq
    from murk.enhance import log_filter, post
    from murk.metrics import affine_psnr, reference
    from murk.metrics import depth as depth_metrics
    from murk.metrics.uciqe import uciqe, uciqe_torch
    from murk.metrics.uiqm import uiqm, uiqm_torch
    from murk.models.jointid import decoder
    from murk.physics import camera, medium
    from murk.physics import forward_scatter as fs
    from murk.restore_ops import affine_transfer as at
    from murk.restore_ops import balance, water
    from murk.scenes.textures import TILE_PX, lookup_numpy, lookup_torch, noise_tile
    from murk.snow.composite import composite_snow, composite_snow_torch

    t = torch.from_numpy
    twins: dict[str, Twin] = {
        "restore_ops.invert_eq1": Twin(
            _water_inputs,
            lambda x: {
                "out": np.stack(
                    [water.invert_eq1(x["images"][i], x["dist"][i], x["veil"][i], x["att"][i], 0.1) for i in range(2)]
                )
            },
            lambda x: {
                "out": water.invert_eq1_torch(t(x["images"]), t(x["dist"]), t(x["veil"]), t(x["att"]), 0.1).numpy()
            },
            atol=2e-6,
        ),
        "physics.distance_map": Twin(
            _medium_inputs,
            lambda x: {"out": x["dist"]},  # made by the numpy twin in _medium_inputs
            lambda x: {"out": medium.distance_map_torch(t(x["depth"])[:, None], t(x["near"]), t(x["far"]))[:, 0]},
            atol=1e-6,
        ),
        "physics.apply_medium": Twin(
            _medium_inputs,
            lambda x: {
                "out": np.stack(
                    [
                        medium.apply_medium(x["images"][i], x["dist"][i], x["beta"][i], x["b_inf"][i])[0]
                        for i in range(2)
                    ]
                )
            },
            lambda x: {
                "out": nhwc(
                    medium.apply_medium_torch(nchw(x["images"]), t(x["dist"])[:, None], t(x["beta"]), t(x["b_inf"]))[0]
                )
            },
            atol=1e-6,
        ),
        "physics.guided_filter (affine_transfer, radius 6)": Twin(
            _transfer_inputs,
            per_image(lambda im, r: at.affine_transfer(im, r, 6, 1e-4), "images", "restored"),
            lambda x: {"out": nhwc(at.affine_transfer_torch(nchw(x["images"]), nchw(x["restored"]), 6, 1e-4))},
            atol=1e-6,
        ),
        "physics.guided_filter (radius 40, beyond half the frame)": Twin(
            _transfer_inputs,
            per_image(lambda im, r: at.affine_transfer(im, r, 40, 1e-3), "images", "restored"),
            lambda x: {"out": nhwc(at.affine_transfer_torch(nchw(x["images"]), nchw(x["restored"]), 40, 1e-3))},
            atol=1e-6,
        ),
        "restore_ops.affine_transfer (step 3, the fast guided filter)": Twin(
            _transfer_inputs,
            per_image(lambda im, r: at.affine_transfer(im, r, 12, 1e-4, step=3), *_IR),
            lambda x: {"out": nhwc(at.affine_transfer_torch(nchw(x["images"]), nchw(x["restored"]), 12, 1e-4, 3))},
            atol=1e-6,
        ),
        "restore_ops.guard_particle_removal": Twin(
            _transfer_inputs,
            per_image(
                lambda im, r: at.guard_particle_removal(im, at.affine_transfer(im, r, 6), r, 0.04, 7),
                "images",
                "restored",
            ),
            lambda x: {
                "out": nhwc(
                    at.guard_particle_removal_torch(
                        nchw(x["images"]),
                        at.affine_transfer_torch(nchw(x["images"]), nchw(x["restored"]), 6),
                        nchw(x["restored"]),
                        0.04,
                        7,
                    )
                )
            },
            atol=1e-6,
        ),
        "restore_ops.color_balance": Twin(
            _murky,
            per_image(lambda im: balance.color_balance(im, 1.0, 2.5), "images"),
            lambda x: {"out": nhwc(balance.color_balance_torch(nchw(x["images"]), 1.0, 2.5))},
            atol=1e-6,
        ),
        "restore_ops.color_balance (a flat channel)": Twin(
            _flat_in_batch,
            per_image(balance.color_balance, "images"),
            lambda x: {"out": nhwc(balance.color_balance_torch(nchw(x["images"])))},
            atol=1e-6,
        ),
        "physics.gaussian_blur": Twin(
            lambda rng: {
                "images": rng.random((3, 13, 17, 3)).astype(np.float32),
                "sigma": np.array([0.545, 1.3, 2.75]),
            },
            lambda x: {
                "out": np.stack([fs.gaussian_blur(im, float(s)) for im, s in zip(x["images"], x["sigma"], strict=True)])
            },
            lambda x: {"out": nhwc(fs.gaussian_blur_torch(nchw(x["images"]), t(x["sigma"])))},
            atol=1e-6,
        ),
        "physics.gaussian_blur (image smaller than the kernel)": Twin(
            lambda rng: {"images": rng.random((1, 3, 4, 3)).astype(np.float32), "sigma": np.array([2.75])},
            lambda x: {"out": fs.gaussian_blur(x["images"][0], 2.75)[None]},
            lambda x: {"out": nhwc(fs.gaussian_blur_torch(nchw(x["images"]), t(x["sigma"])))},
            atol=1e-6,
        ),
        "enhance.laplacian_of_gaussian": Twin(
            _murky,
            per_image(log_filter.laplacian_of_gaussian, "images"),
            lambda x: {"out": nhwc(log_filter.laplacian_of_gaussian_torch(nchw(x["images"])))},
            atol=1e-6,
        ),
        "enhance.laplacian_of_gaussian (image smaller than the kernel)": Twin(
            _images(1, 3, 4),
            per_image(log_filter.laplacian_of_gaussian, "images"),
            lambda x: {"out": nhwc(log_filter.laplacian_of_gaussian_torch(nchw(x["images"])))},
            atol=1e-6,
        ),
        "metrics.psnr": Twin(
            _pairs(3, 9, 11, 0.02),
            lambda x: {
                "out": np.array(
                    [reference.psnr(p, r, data_range=1.0) for p, r in zip(x["pred"], x["ref"], strict=True)]
                )
            },
            lambda x: {"out": reference.psnr_torch(nchw(x["pred"]), nchw(x["ref"]), data_range=1.0).numpy()},
            atol=0.0,
            rtol=1e-12,
        ),
        "metrics.affine_fit_psnr": Twin(
            _pairs(3, 9, 11, 0.05),
            lambda x: {
                "out": np.array(
                    [
                        affine_psnr.affine_fit_psnr(p, r, data_range=1.0)
                        for p, r in zip(x["pred"], x["ref"], strict=True)
                    ]
                )
            },
            lambda x: {
                "out": affine_psnr.affine_fit_psnr_torch(nchw(x["pred"]), nchw(x["ref"]), data_range=1.0).numpy()
            },
            atol=0.0,
            rtol=1e-10,
        ),
        "metrics.depth_errors": Twin(
            _depth_inputs,
            lambda x: {
                k: np.array(
                    [getattr(depth_metrics.depth_errors(p, g), k) for p, g in zip(x["pred"], x["gt"], strict=True)]
                )
                for k in depth_metrics.DEPTH_ERROR_NAMES
            },
            lambda x: {
                k: getattr(depth_metrics.depth_errors_torch(t(x["pred"])[:, None], t(x["gt"])[:, None]), k).numpy()
                for k in depth_metrics.DEPTH_ERROR_NAMES
            },
            atol=1e-12,
            rtol=1e-10,
        ),
    }
    for window in ("gaussian", "uniform"):
        twins[f"metrics.ssim ({window})"] = Twin(
            _pairs(2, 33, 47, 0.1),
            lambda x, w=window: {
                "out": np.array(
                    [reference.ssim(p, r, data_range=1.0, window=w) for p, r in zip(x["pred"], x["ref"], strict=True)]
                )
            },
            lambda x, w=window: {
                "out": reference.ssim_torch(nchw(x["pred"]), nchw(x["ref"]), data_range=1.0, window=w).numpy()
            },
            atol=0.0,
            rtol=1e-10,
        )
    for he in ("y", "rgb", "clahe"):
        twins[f"enhance.equalize ({he})"] = Twin(
            _murky,
            lambda x, he=he: {"out": np.stack([eq.equalize(im, he) for im in x["images"]])},
            lambda x, he=he: {"out": nhwc(eq.equalize_torch(nchw(x["images"]), he))},
            atol=0.0,  # the same 8-bit lookup tables: bit-identical
        )
        twins[f"enhance.post_process ({he})"] = Twin(
            _murky,
            lambda x, he=he: {
                "out": np.stack([post.post_process(im, he=he, clahe_tiles=(4, 3)) for im in x["images"]])
            },
            lambda x, he=he: {"out": nhwc(post.post_process_torch(nchw(x["images"]), he=he, clahe_tiles=(4, 3)))},
            atol=1e-6,
        )
        twins[f"enhance.post_process ({he}, he_strength 0.3)"] = Twin(
            _murky,
            lambda x, he=he: {
                "out": np.stack(
                    [post.post_process(im, he=he, clahe_tiles=(4, 3), lam=0.1, he_strength=0.3) for im in x["images"]]
                )
            },
            lambda x, he=he: {
                "out": nhwc(
                    post.post_process_torch(nchw(x["images"]), he=he, clahe_tiles=(4, 3), lam=0.1, he_strength=0.3)
                )
            },
            atol=1e-6,
        )
    twins["physics.apply_camera"] = Twin(
        _images(3, 24, 40),
        lambda x: {
            "out": np.stack([camera.apply_camera(im, p) for im, p in zip(x["images"], _camera_params(), strict=True)])
        },
        lambda x: {"out": nhwc(camera.apply_camera_torch(nchw(x["images"]), _camera_params()))},
        atol=0.0,  # the same noise field and the same OpenCV quantisation and JPEG round trip: bit-identical
    )
    for mode in ("approx", "exact"):
        twins[f"physics.forward_scatter ({mode})"] = Twin(
            _scatter_inputs,
            lambda x, m=mode: _stack_outputs(
                [fs.forward_scatter(im, d, mode=m, step_px=0.25) for im, d in zip(x["images"], x["dist"], strict=True)]
            ),
            lambda x, m=mode: _torch_outputs(
                fs.forward_scatter_torch(nchw(x["images"]), t(x["dist"])[:, None], mode=m, step_px=0.25)
            ),
            atol=2e-6,
            rtol=1e-6,
        )
    twins["snow.composite_snow"] = Twin(
        _images(3, 45, 55),
        lambda x: _stack_snow(
            [composite_snow(im, p, _snow_bank()) for im, p in zip(x["images"], _snow_params(), strict=True)]
        ),
        lambda x: _torch_snow(composite_snow_torch(nchw(x["images"]), _snow_params(), _snow_bank())),
        atol=1e-5,  # Eq. (8) blurs with separable float32 kernels in a different summation order
    )
    twins["scenes.texture_lookup"] = Twin(
        lambda rng: {
            "x": (rng.random((40, 30)) * TILE_PX).astype(np.float32),
            "y": (rng.random((40, 30)) * TILE_PX).astype(np.float32),
        },
        lambda x: {"out": lookup_numpy(noise_tile(), x["x"], x["y"])},
        lambda x: {"out": lookup_torch(torch.from_numpy(np.array(noise_tile())), t(x["x"]), t(x["y"])).numpy()},
        atol=2e-6,
    )
    for r in (2, 4, 8):  # Joint-ID's shuffle smoothing: OpenCV's separable filter in CPU inference, else pooling
        twins[f"models.jointid.smooth_shuffled (r={r})"] = Twin(
            lambda rng: {"maps": rng.random((3, 37, 53, 2)).astype(np.float32)},
            lambda x, r=r: {
                "out": np.stack([nhwc(decoder._smooth_shuffled_opencv(nchw(m[None]), r))[0] for m in x["maps"]])
            },
            lambda x, r=r: {"out": nhwc(decoder._smooth_shuffled_torch(nchw(x["maps"]), r))},
            atol=5e-7,  # the same triangle, summed in another order
        )
    uiqm_tolerance = {"uicm": 1e-4, "uism": 1e-5, "uiconm": 1e-6}
    for preset in ("panetta2016", "funie", "jointid"):
        for part, rtol in uiqm_tolerance.items():
            twins[f"metrics.uiqm.{part} ({preset})"] = Twin(
                _images(2, 37, 45),
                lambda x, p=preset, k=part: {
                    "out": np.array([getattr(uiqm(im, data_range=1.0, preset=p), k) for im in x["images"]])
                },
                lambda x, p=preset, k=part: {
                    "out": getattr(uiqm_torch(nchw(x["images"]), data_range=1.0, preset=p), k).numpy()
                },
                atol=0.0,
                rtol=rtol,
            )
    for preset in ("uciqe_m", "cielab_raw"):
        twins[f"metrics.uciqe ({preset})"] = Twin(
            _flat_in_batch,
            lambda x, p=preset: {
                k: np.array([getattr(uciqe(im, data_range=1.0, preset=p), k) for im in x["images"]])
                for k in ("uciqe", "sigma_c", "con_l", "mu_s")
            },
            lambda x, p=preset: {
                k: getattr(uciqe_torch(nchw(x["images"]), data_range=1.0, preset=p), k).numpy()
                for k in ("uciqe", "sigma_c", "con_l", "mu_s")
            },
            atol=1e-7,
            rtol=1e-9,
        )
    return twins


@functools.cache
def _snow_bank() -> Any:
    """The particle bank shipped with murk (loaded once)."""
    from murk.data import default_snow_bank
    from murk.snow.bank import load_bank

    return load_bank(default_snow_bank())


def _snow_params() -> list[Any]:
    from murk.snow.composite import sample_snow

    return [sample_snow(seed, _snow_bank(), n_particles=(200, 300)) for seed in range(3)]


def _stack_snow(results: list[tuple[np.ndarray, np.ndarray]]) -> Arrays:
    return {"image": np.stack([r[0] for r in results]), "alpha": np.stack([r[1] for r in results])}


def _torch_snow(result: tuple[torch.Tensor, torch.Tensor]) -> Arrays:
    return {"image": nhwc(result[0]), "alpha": result[1][:, 0].numpy()}


def _stack_outputs(results: list[tuple[np.ndarray, float]]) -> Arrays:
    return {"image": np.stack([r[0] for r in results]), "sigma_max": np.array([r[1] for r in results])}


def _torch_outputs(result: tuple[torch.Tensor, torch.Tensor]) -> Arrays:
    return {"image": nhwc(result[0]), "sigma_max": result[1].reshape(-1).numpy()}


def _camera_params() -> list[Any]:
    """Three camera settings: JPEG at quality 70, none (quantisation only), and a strong cast with JPEG 95."""
    from murk.synth.params import CameraParams

    return [
        CameraParams((1.1, 0.95, 0.96), 1.2, 0.01, 0.0004, 7, 70),
        CameraParams((1.0, 1.0, 1.0), 1.0, 0.0, 0.0, 8, 0),
        CameraParams((1.4, 0.8, 0.9), 0.8, 0.005, 0.0001, 9, 95),
    ]


TWINS: dict[str, Twin] = _table()
"""Every numpy/torch twin pair, by name, with its tolerance."""
