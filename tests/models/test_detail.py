"""The detail network (murk.models.detail): its shape rules, its file format and the shipped weights."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from murk.data import sample_underwater_images, shipped_detail_weights
from murk.enhance.restorer import create
from murk.errors import InputFileError
from murk.io import read_rgb
from murk.models.detail import DEFAULT_CHANNELS, DetailNet, load_detail, save_detail
from murk.report.compare import downscale_to


def test_an_untrained_network_changes_nothing_and_keeps_any_size() -> None:
    net = DetailNet(6)
    x = torch.rand(2, 3, 37, 53)
    assert net(x).shape == x.shape
    torch.testing.assert_close(net.detailed(x), x, rtol=0, atol=0)
    for bad in (0, 2.5, True, 300):
        with pytest.raises(ValueError, match="channels"):
            DetailNet(bad)  # type: ignore[arg-type]


def test_a_saved_network_reads_back_the_same(tmp_path: Path) -> None:
    torch.manual_seed(1)
    net = DetailNet(5)
    for conv in net.convs:
        torch.nn.init.normal_(conv.weight, std=0.1)
    path = save_detail(net, tmp_path / "d.npz", {"steps": 3})
    again, meta = load_detail(path)
    assert meta == {"steps": 3, "channels": 5} and not again.training
    x = torch.rand(1, 3, 20, 24)
    with torch.no_grad():
        torch.testing.assert_close(again(x), net(x), rtol=0, atol=0)


def test_a_missing_or_foreign_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="not found") as missing:
        load_detail(tmp_path / "none.npz")
    assert "none.npz" in str(missing.value)
    np.savez(tmp_path / "other.npz", w1=np.zeros(3), meta=np.array('{"channels": 4}'))
    with pytest.raises(InputFileError, match="not a murk detail network") as other:
        load_detail(tmp_path / "other.npz")
    assert "other.npz" in str(other.value)


def test_the_network_cannot_tell_where_the_frame_ends() -> None:
    """Borders are padded by repetition: a flat image gets the same residual everywhere (with zero padding the
    trained network tinted the top rows red, where the training scenes' far water was)."""
    torch.manual_seed(2)
    net = DetailNet(4)
    for conv in net.convs:
        torch.nn.init.normal_(conv.weight, std=0.3)
    with torch.no_grad():
        r = net(torch.full((1, 3, 30, 40), 0.4))
    torch.testing.assert_close(r, r[:, :, :1, :1].expand_as(r), rtol=0, atol=1e-6)


def test_the_shipped_network_keeps_lites_colour_and_changes_its_detail() -> None:
    net, meta = load_detail()
    assert net.channels == DEFAULT_CHANNELS and meta["base"] == "lite" and meta["scenes"] >= 1000
    assert shipped_detail_weights().stat().st_size < 200_000
    image = downscale_to(read_rgb(sample_underwater_images()[0]), 320)
    lite = np.clip(create("lite").restore(image[None]).images[0], 0, 1)
    out = create("lite+detail").restore(image[None]).images[0]
    change = out - lite
    assert np.abs(change).mean() > 0.002  # it does something ...
    assert np.abs(change.mean(axis=(0, 1))).max() < 0.01  # ... and leaves the colour alone


def test_bands_of_rows_give_the_whole_frame_result() -> None:
    torch.manual_seed(3)
    net = DetailNet(5)
    for conv in net.convs:
        torch.nn.init.normal_(conv.weight, std=0.2)
    x = torch.rand(2, 3, 41, 23)
    with torch.no_grad():
        whole = (x + 0.7 * net(x)).clamp(0, 1)
        for band_px in (23, 23 * 5, 23 * 40, 10**6):  # one row, a few rows, a last short band, one pass
            torch.testing.assert_close(net.detailed(x, 0.7, band_px=band_px), whole, rtol=0, atol=1e-6)


@pytest.mark.parametrize("content", ["empty", "cut", "npy", "meta list", "no channels"])
def test_a_broken_weights_file_is_named_with_its_problem(tmp_path: Path, content: str) -> None:
    path = tmp_path / "broken.npz"
    good = save_detail(DetailNet(3), tmp_path / "good.npz")
    if content == "empty":
        path.write_bytes(b"")
    elif content == "cut":
        path.write_bytes(good.read_bytes()[:200])
    elif content == "npy":
        with path.open("wb") as fh:
            np.save(fh, np.zeros(3))
    else:
        with np.load(good) as z:
            arrays = {k: z[k] for k in z.files if k != "meta"}
        meta = "[1]" if content == "meta list" else '{"channels": null}'
        np.savez(path, **arrays, meta=np.array(meta))
    with pytest.raises(InputFileError, match="not a murk detail network") as err:
        load_detail(path)
    assert "broken.npz" in str(err.value)
