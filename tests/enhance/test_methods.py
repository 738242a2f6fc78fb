"""The declarations of the built-in methods (murk.enhance.methods): the registry serves each one, knows every name
and option without importing torch or OpenCV (and, asked to, whether a given weights file is there), checks
declared ranges, the docs' options table is the declarations, and building one builds the real restorer; a
method's device is read without building the default one."""

from __future__ import annotations

import importlib
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

from murk.enhance import methods
from murk.enhance.choices import DEFAULT_LITE_BLEND
from murk.enhance.declare import Method, Preset
from murk.enhance.restorer import Chain, Restorer, check, create, declaration, device_type, options_of


@pytest.mark.parametrize("method", [m for m in methods.BUILTIN if isinstance(m, Method)], ids=lambda m: m.name)
def test_each_builtin_method_is_declared_once_and_served_by_the_registry(method: Method) -> None:
    assert options_of(method.name) == method.option_map and declaration(method.name) is method
    for option in method.options:
        assert option.help and "\n" not in option.help, (method.name, option.name)
        assert option.type in str(option) and option.default == dict(method.option_map)[option.name].default
        if "torch" not in option.type:  # resolved without torch; torch.device is checked by the implementation
            assert option.annotation is not Any, (method.name, option.name)
    module, _, name = str(method.implementation).partition(":")
    assert callable(getattr(importlib.import_module(module), name))


def test_jointid_is_a_preset_blending_the_shipped_lite_into_jointid_net() -> None:
    preset = declaration("jointid")
    assert isinstance(preset, Preset) and preset in methods.BUILTIN
    assert (preset.spec, preset.first) == ("jointid_net|lite@lite_blend", "jointid_net")
    assert preset.passes == ("device", "exposure")
    assert options_of("jointid") == {**options_of("jointid_net"), "lite_blend": preset.options[0]}
    assert preset.options[0].default == DEFAULT_LITE_BLEND and "lite_blend" not in options_of("jointid_net")
    assert "jointid = jointid_net|lite@lite_blend: " in methods.methods_help()


def test_options_are_checked_against_their_declared_ranges() -> None:
    with pytest.raises(ValueError, match=r"option lite_blend: expected a number in \[0.0, 1.0\], got 1.5"):
        check("jointid?lite_blend=1.5")
    with pytest.raises(ValueError, match=r"option batch: expected a number in \[1.0, inf\], got 0.0"):
        check("lite", batch=0)
    with pytest.raises(ValueError, match=r"option strength: expected a number in \[0.0, 1.0\], got nan"):
        check("greyworld", strength=float("nan"))
    check("jointid?lite_blend=1,tile=0")  # the ends are in range


def test_the_docs_table_of_options_is_the_declarations() -> None:
    text = (Path(__file__).parents[2] / "docs" / "enhance.md").read_text(encoding="utf-8")
    start, end = "<!-- options table: murk.enhance.methods.options_table() -->\n", "\n<!-- end of options table -->"
    assert start in text and end in text
    assert text.split(start)[1].split(end)[0] == methods.options_table()


def test_names_and_options_are_checked_without_torch() -> None:
    code = textwrap.dedent(
        """
        import sys
        from murk.enhance.restorer import available, create, options_of
        names = ["clahe", "colorbalance", "desnow", "detail", "greyworld", "jointid", "jointid_net", "lite", "post",
                 "udaformer", "udcp", "ursct", "water"]
        assert available() == names
        assert options_of("jointid")["overlap"].default == 64
        for spec, text in [
            ("jointd", "unknown 'jointd' (did you mean 'jointid'?)"),
            ("post?lamda=1", "unknown option 'lamda' (did you mean 'lam'?)"),
            ("post?lam=abc", "option lam: expected float | None, got 'abc'"),
            ("jointid?precision=fp64", "option precision: expected one of 'fp32', 'bf16', 'fp16', got 'fp64'"),
            ("jointid_net|lite@1.5", "expected a weight in [0, 1] after '@', got 1.5"),
            ("jointid|lite", "the blend with 'lite' needs a weight"),
        ]:
            try:
                create(spec)
            except ValueError as exc:
                assert text in str(exc), (spec, str(exc))
            else:
                raise AssertionError(spec)
        print(sorted(m for m in ("torch", "onnxruntime", "cv2") if m in sys.modules))
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_check_with_files_reports_a_missing_weights_file_without_torch(tmp_path: Path) -> None:
    missing = tmp_path / "missing"
    code = textwrap.dedent(
        f"""
        import sys
        from murk.enhance.restorer import check
        from murk.errors import InputFileError
        check("jointid?checkpoint={missing}.pt")  # names and options only
        for spec, text in [
            ("jointid?checkpoint={missing}.pt", "checkpoint not found"),
            ("lite+post?onnx={missing}.onnx", "ONNX model not found"),
            ("ursct?checkpoint={missing}.pth", "checkpoint not found"),
            ("post+udaformer?checkpoint={missing}.pth", "checkpoint not found"),
            ("colorbalance|jointid_net@0.5?checkpoint={missing}.pt", "checkpoint not found"),
        ]:
            try:
                check(spec, files=True)
            except InputFileError as exc:
                assert text in str(exc) and "{missing}" in str(exc), (spec, str(exc))
            else:
                raise AssertionError(spec)
        check("colorbalance+post?lam=0.2", files=True)  # nothing to check
        print(sorted(m for m in ("torch", "onnxruntime", "cv2") if m in sys.modules))
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_device_type_leaves_the_default_cpu_device_unbuilt() -> None:
    import torch

    chain = create("greyworld+clahe")
    assert device_type(chain) == "cpu" and "device" not in vars(chain)  # the lazy default, not a torch.device
    assert chain.device == torch.device("cpu")  # built when read
    assert device_type(create("post", shared={"device": "cpu"})) == "cpu"

    class OnCuda(Restorer):
        device = "cuda:1"  # type: ignore[assignment]

    on_cuda = OnCuda()
    assert device_type(on_cuda) == "cuda" and device_type(Chain([on_cuda, chain])) == "cuda"
    stage = Restorer()
    stage.device = torch.device("cuda", 0)
    assert device_type(stage) == "cuda" and device_type(Chain([stage])) == "cuda"


def test_a_lazy_factory_builds_the_real_restorer() -> None:
    from murk.enhance.post import POST_PRESETS, PostRestorer

    restorer = create("post?preset=paper", shared={"device": "cpu"})
    assert isinstance(restorer, PostRestorer)
    assert restorer.params == POST_PRESETS["paper"]


@pytest.mark.parametrize(
    "spec", ["colorbalance", "greyworld", "clahe", "udcp", "desnow", "detail", "lite", "post", "lite+detail"]
)
def test_every_method_refuses_integer_frames_and_names_the_conversion(spec: str) -> None:
    import numpy as np

    frames = np.full((1, 16, 16, 3), 128, np.uint8)  # 8-bit values: 85 % of them read as saturated floats
    with pytest.raises(TypeError, match=r"expected a float array in \[0, 1\], got dtype uint8 \(murk.io.to_float"):
        create(spec).restore(frames)
    out = create(spec).restore(frames.astype(np.float32) / 255)
    assert out.images.dtype == np.float32 and 0.0 <= out.images.min() and out.images.max() <= 1.0
