"""tools/check_wheel.py (make wheel-check, run by CI from .ci/run): the wheel's contents and licence metadata are
checked, a deprecation warning of the build fails it, and the whole check passes on the checkout (slow: it builds,
installs and runs murk, about 25 s)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # pytest's own dependency on Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
_PATH = ROOT / "tools" / "check_wheel.py"
_spec = importlib.util.spec_from_file_location("check_wheel", _PATH)
assert _spec is not None and _spec.loader is not None
cw = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cw)

METADATA = """Metadata-Version: 2.4
Name: murk
Version: 0.1.0
License-Expression: Apache-2.0 AND MIT AND CC-BY-3.0
Classifier: Programming Language :: Python :: 3
License-File: LICENSE
"""


def _wheel(path: Path, names: list[str], metadata: str = METADATA) -> Path:
    with zipfile.ZipFile(path, "w") as z:
        for name in names:
            z.writestr(name, b"x")
        z.writestr("murk-0.1.0.dist-info/METADATA", metadata)
    return path


def test_the_shipped_files_are_listed_from_the_package_data_of_pyproject() -> None:
    expected = cw.expected_files()
    assert {"murk/__init__.py", "murk/py.typed", "murk/live/assets/live.js", "murk/live/assets/index.html"} <= set(
        expected
    )
    assert {"murk/data/models/jointid-small.pt", "murk/data/models/lite.pt", "murk/data/snow/default_bank.npz"} <= set(
        expected
    )
    assert not [n for n in expected if "__pycache__" in n or n.endswith(".pyc")]
    package_data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert tuple(package_data["murk"]) == cw.DATA_PATTERNS  # the check looks for what setuptools ships
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert tuple(project["license-files"]) == cw.LICENSE_FILES and isinstance(project["license"], str)


def test_a_wheel_without_a_shipped_file_with_another_package_or_with_old_licence_metadata_is_refused(
    tmp_path: Path,
) -> None:
    licences = [f"murk-0.1.0.dist-info/licenses/{f}" for f in cw.LICENSE_FILES]
    expected = ["murk/__init__.py", "murk/data/models/lite.pt", "murk/live/assets/live.js"]
    good = _wheel(tmp_path / "good.whl", [*expected, *licences])
    assert cw.wheel_problems(good, expected) == []
    short = _wheel(tmp_path / "short.whl", ["murk/__init__.py", "murk/live/assets/live.js", *licences[:1]])
    assert cw.wheel_problems(short, expected) == [
        "missing murk/data/models/lite.pt",
        "missing licence file src/murk/data/DATA_LICENSES.md",
    ]
    extra = _wheel(tmp_path / "extra.whl", [*expected, *licences, "testkit/__init__.py", "tests/conftest.py"])
    assert cw.wheel_problems(extra, expected) == [
        "ships testkit/__init__.py (only murk/ and its .dist-info belong in the wheel)",
        "ships tests/conftest.py (only murk/ and its .dist-info belong in the wheel)",
    ]
    old = METADATA.replace("License-Expression: Apache-2.0 AND MIT AND CC-BY-3.0\n", "License: Apache-2.0\n")
    old += "Classifier: License :: OSI Approved :: Apache Software License\n"
    assert cw.wheel_problems(_wheel(tmp_path / "old.whl", [*expected, *licences], old), expected) == [
        "METADATA has no License-Expression (PEP 639)",
        "METADATA has a deprecated licence classifier: Classifier: License :: OSI Approved :: Apache Software License",
    ]


def test_deprecation_warnings_of_the_build_are_found() -> None:
    # what setuptools 84 printed for the licence table and classifier before issue 49
    output = (
        "running egg_info\n"
        "/tmp/env/setuptools/config/_apply_pyprojecttoml.py:82: SetuptoolsDeprecationWarning: `project.license` as a "
        "TOML table is deprecated\n"
        "warning: build_py: byte-compiling is disabled, skipping.\n"
        "        !!\n"
    )
    assert cw.deprecations(output) == [
        "/tmp/env/setuptools/config/_apply_pyprojecttoml.py:82: SetuptoolsDeprecationWarning: `project.license` as a "
        "TOML table is deprecated"
    ]
    assert cw.deprecations("Successfully built murk-0.1.0.tar.gz and murk-0.1.0-py3-none-any.whl\n") == []


def test_keep_refuses_a_folder_inside_the_checkout() -> None:
    assert cw.main(["--keep", str(ROOT / "wheel-check")]) == 2
    assert not (ROOT / "wheel-check").exists()


@pytest.mark.slow
def test_the_wheel_check_passes_on_the_checkout(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run(
        [sys.executable, str(_PATH), "--keep", str(tmp_path / "check")],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=1200,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "no deprecation warning" in proc.stdout and "pip check: ok" in proc.stdout
    assert "stopped by Ctrl+C (exit 130)" in proc.stdout and "wheel check passed" in proc.stdout
