"""The lazy factories of the torch methods (murk.enhance.methods): the registry knows every name and option without
importing torch (and, asked to, whether a given weights file is there), each declaration equals the factory it
calls, and calling one builds the real restorer; a method's device is read without building the default one."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from murk.enhance import methods
from murk.enhance.options import declared_options
from murk.enhance.restorer import Chain, Restorer, create, device_type, options_of


def _implementation(name: str):  # type: ignore[no-untyped-def]
    from murk.enhance import jointid_restorer, lite_restorer, post, udaformer_restorer, ursct_restorer

    return {
        "post": post.make_post,
        "jointid": jointid_restorer.create_jointid,
        "lite": lite_restorer.create_lite,
        "udaformer": udaformer_restorer.create_udaformer,
        "ursct": ursct_restorer.create_ursct,
    }[name]


@pytest.mark.parametrize("name", ["post", "jointid", "lite", "udaformer", "ursct"])
def test_the_declaration_equals_the_implementation(name: str) -> None:
    lazy = declared_options(getattr(methods, name))
    real = declared_options(_implementation(name))
    assert [(o.name, o.type, o.default) for o in lazy.values()] == [(o.name, o.type, o.default) for o in real.values()]
    # the annotations the implementation resolves are resolved the same (torch.device only there)
    for key, option in lazy.items():
        if "torch" not in option.type:
            assert option.annotation == real[key].annotation, key
    assert options_of(name) == lazy


def test_names_and_options_are_checked_without_torch() -> None:
    code = textwrap.dedent(
        """
        import sys
        from murk.enhance.restorer import available, create, options_of
        names = ["clahe", "colorbalance", "greyworld", "jointid", "lite", "post", "udaformer", "udcp", "ursct"]
        assert available() == names
        assert options_of("jointid")["overlap"].default == 64
        for spec, text in [
            ("jointd", "unknown 'jointd' (did you mean 'jointid'?)"),
            ("post?lamda=1", "unknown option 'lamda' (did you mean 'lam'?)"),
            ("post?lam=abc", "option lam: expected float | None, got 'abc'"),
            ("jointid?precision=fp64", "option precision: expected one of 'fp32', 'bf16', 'fp16', got 'fp64'"),
        ]:
            try:
                create(spec)
            except ValueError as exc:
                assert text in str(exc), (spec, str(exc))
            else:
                raise AssertionError(spec)
        print(sorted(m for m in ("torch", "onnxruntime") if m in sys.modules))
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
        ]:
            try:
                check(spec, files=True)
            except InputFileError as exc:
                assert text in str(exc) and "{missing}" in str(exc), (spec, str(exc))
            else:
                raise AssertionError(spec)
        check("colorbalance+post?lam=0.2", files=True)  # nothing to check
        print(sorted(m for m in ("torch", "onnxruntime") if m in sys.modules))
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
