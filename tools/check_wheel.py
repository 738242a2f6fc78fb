"""murk as a user installs it: build the sdist and the wheel, install the wheel in a fresh virtual environment
outside the checkout, and run murk from there (issue 49; ``make wheel-check``, which CI runs from ``.ci/run``).

    python tools/check_wheel.py [--keep DIR]

1. ``python -m build --no-isolation`` builds the sdist and, from the sdist, the wheel (so a file missing from the
   sdist is missing from the wheel too). A deprecation warning of the build backend fails the check: the licence
   metadata is PEP 639's (an SPDX ``license`` string and ``license-files``).
2. The wheel holds every module and every shipped data file of the checkout (the Joint-ID and lite weights, the
   snow banks, the sample images, the live page's assets) and the licence files; its metadata has the SPDX
   expression and no licence classifier.
3. A fresh virtual environment in a temporary folder gets the wheel (``pip install --no-deps``: not editable, no
   network). murk's dependencies come from the environment running this script: one ``.pth`` line appends its
   site-packages after the new environment's own, so the torch ``make install`` chose is reused offline, while
   murk itself can only come from the wheel. ``pip check`` there: every requirement the wheel declares is met.
4. From a folder outside the checkout, without ``PYTHONPATH``: murk and its data are imported from the new
   environment; ``murk --version`` prints the wheel's version; ``murk snow info`` reads each shipped bank;
   ``murk enhance`` restores a shipped sample image with the default method and with ``jointid``, each with the
   shipped weights (its weights line names files of the new environment); ``murk live`` (default method) starts
   on a shipped sample image, its page, script and style sheet are fetched once over 127.0.0.1, and Ctrl+C stops
   it (exit 130).

Exit code 0 when every step passed, 1 otherwise (the failed step is named).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import sysconfig
import tempfile
import time
import urllib.request
import zipfile
from collections.abc import Iterable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "src" / "murk"
DATA_PATTERNS = ("py.typed", "data/**/*", "live/assets/*")
"""What ``[tool.setuptools.package-data]`` ships besides the modules (kept in step with pyproject.toml)."""
LICENSE_FILES = ("LICENSE", "src/murk/data/DATA_LICENSES.md")
BANKS = ("builtin:snow", "builtin:snow-real", "builtin:snow-small")
STEP_TIMEOUT_S = 600.0
"""Limit of one step (building, installing, one command): only a fault reaches it."""


class CheckFailed(Exception):
    """A step of the check failed; the message says which and why."""


def deprecations(output: str) -> list[str]:
    """The lines of a build's output that announce a deprecation."""
    return [line.strip() for line in output.splitlines() if re.search(r"deprecat", line, re.IGNORECASE)]


def expected_files(package: Path = PACKAGE) -> list[str]:
    """The files the wheel must hold under ``murk/``: every module and every file of ``DATA_PATTERNS``."""
    files = {p for p in package.rglob("*.py")}
    for pattern in DATA_PATTERNS:
        files |= set(package.glob(pattern))
    return sorted(
        f"murk/{p.relative_to(package).as_posix()}" for p in files if p.is_file() and "__pycache__" not in p.parts
    )


def wheel_problems(wheel: Path, expected: Iterable[str]) -> list[str]:
    """What is wrong with ``wheel``: files it lacks (``expected`` and the licence files), files outside ``murk/``
    (``testkit/``, ``tests/``: never shipped), licence metadata."""
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        dist_info = next((n.split("/")[0] for n in names if n.endswith(".dist-info/METADATA")), None)
        if dist_info is None:
            return ["no .dist-info/METADATA"]
        metadata = z.read(f"{dist_info}/METADATA").decode("utf-8")
    problems = [f"missing {name}" for name in expected if name not in names]
    problems += [
        f"ships {n} (only murk/ and its .dist-info belong in the wheel)"
        for n in sorted(names)
        if not n.startswith(("murk/", f"{dist_info}/"))
    ]  # e.g. testkit/, the tests' and benchmarks' helpers
    problems += [f"missing licence file {f}" for f in LICENSE_FILES if f"{dist_info}/licenses/{f}" not in names]
    if not re.search(r"^License-Expression: \S", metadata, re.MULTILINE):
        problems.append("METADATA has no License-Expression (PEP 639)")
    classifiers = re.findall(r"^Classifier: License ::.*$", metadata, re.MULTILINE)
    problems += [f"METADATA has a deprecated licence classifier: {c}" for c in classifiers]
    return problems


def run(cmd: list[str], *, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """``cmd`` with its output captured; CheckFailed unless it exits 0."""
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=STEP_TIMEOUT_S, check=False)
    if proc.returncode != 0:
        raise CheckFailed(f"{' '.join(cmd)} exited with {proc.returncode}:\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}")
    return proc


def build(dist: Path) -> tuple[Path, Path]:
    """The sdist and the wheel built from it; CheckFailed on a deprecation warning."""
    try:
        import build  # noqa: F401
    except ImportError:
        raise CheckFailed("needs the 'build' package (murk's dev extra has it): pip install build") from None
    proc = run([sys.executable, "-m", "build", "--no-isolation", "--outdir", str(dist), str(ROOT)], cwd=dist.parent)
    warned = deprecations(proc.stdout + proc.stderr)
    if warned:
        raise CheckFailed("the build warns of deprecations:\n" + "\n".join(warned))
    (sdist,), (wheel,) = sorted(dist.glob("*.tar.gz")), sorted(dist.glob("*.whl"))
    return sdist, wheel


def dependency_dirs() -> list[Path]:
    """Where this interpreter's packages are: murk's dependencies for the new environment."""
    return [Path(p) for p in dict.fromkeys(sysconfig.get_paths()[k] for k in ("purelib", "platlib"))]


def make_env(venv: Path, wheel: Path) -> tuple[Path, dict[str, str]]:
    """A fresh virtual environment with ``wheel`` installed, murk's dependencies from this interpreter's
    site-packages; its python and the environment to run it in."""
    run([sys.executable, "-m", "venv", "--without-pip", str(venv)], cwd=venv.parent)  # pip runs from here
    python = venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    where = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    site = Path(run([str(python), "-c", where], cwd=venv).stdout.strip())
    (site / "_murk_wheel_check_deps.pth").write_text("".join(f"{p}\n" for p in dependency_dirs()))  # after site
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["PATH"] = os.pathsep.join([str(python.parent), env.get("PATH", "")])
    pip = [sys.executable, "-m", "pip", "--python", str(python)]
    run([*pip, "install", "-q", "--no-deps", "--no-index", str(wheel)], cwd=venv, env=env)
    run([*pip, "check"], cwd=venv, env=env)
    return python, env


PROBE = """
import json, sys
import murk, murk.data as d
from murk.live.page import ASSETS
print(json.dumps({
    "murk": murk.__file__, "version": murk.__version__, "path": sys.path,
    "files": [str(p) for p in (d.shipped_jointid_weights(), d.shipped_lite_weights(), d.shipped_water_weights(),
                               d.default_snow_bank(), d.real_footage_snow_bank(), d.small_snow_bank())],
    "assets": sorted(ASSETS), "sample": str(d.sample_underwater_images()[0]),
}))
"""


def inside(path: str | Path, folder: Path) -> bool:
    return Path(path).resolve().is_relative_to(folder.resolve())


def check_installed(python: Path, env: dict[str, str], venv: Path, work: Path, version: str) -> list[str]:
    """Run murk from the new environment (see the module docstring, step 4); the lines to print."""
    done: list[str] = []
    probe = json.loads(run([str(python), "-c", PROBE], cwd=work, env=env).stdout.strip().splitlines()[-1])
    if not inside(probe["murk"], venv):
        raise CheckFailed(f"murk was imported from {probe['murk']}, not from the new environment {venv}")
    deps = dependency_dirs()
    leaks = [p for p in probe["path"] if p and inside(p, ROOT) and not any(inside(p, d) for d in deps)]
    if leaks:  # the dependencies may live in the checkout's .venv; the source tree must not be reachable
        raise CheckFailed(f"the checkout is on the new environment's sys.path: {leaks}")
    absent = [f for f in probe["files"] if not (inside(f, venv) and Path(f).is_file())]
    if absent or probe["version"] != version:
        raise CheckFailed(f"shipped files not in the new environment: {absent}; version {probe['version']}")
    done.append(f"murk {version} imported from the wheel, with {len(probe['files'])} shipped weights and banks")

    murk = str(python.parent / "murk")
    said = run([murk, "--version"], cwd=work, env=env).stdout.strip()
    if said != f"murk {version}":
        raise CheckFailed(f"murk --version printed {said!r}, expected 'murk {version}'")
    done.append(f"murk --version: {said}")

    for bank in BANKS:
        info = json.loads(run([murk, "snow", "info", bank], cwd=work, env=env).stdout)
        if info.get("particles", 0) <= 0:
            raise CheckFailed(f"murk snow info {bank}: no particles ({info})")
    done.append(f"murk snow info: {', '.join(BANKS)} read")

    sample = Path(probe["sample"])
    for method in (None, "jointid", "lite+detail"):  # the default, the larger weights file, an .npz network
        out = work / f"enhanced-{method or 'default'}"
        chosen = ["--method", method] if method else []
        proc = run([murk, "enhance", str(sample), "--out", str(out), *chosen], cwd=work, env=env)
        text = proc.stdout + proc.stderr
        weights = re.findall(r"(\S+\.(?:pt|npz))\b", text)
        if not (out / sample.name).is_file() or not weights or not all(inside(w, venv) for w in weights):
            raise CheckFailed(f"murk enhance {sample.name}: no output, or weights outside the new environment:\n{text}")
        names = ", ".join(Path(w).name for w in weights)
        done.append(f"murk enhance {sample.name} ({method or 'default method'}): shipped weights {names}")

    estimates = work / "water.jsonl"
    proc = run([murk, "water", "estimate", str(sample), "--json", str(estimates)], cwd=work, env=env)
    rows = [json.loads(line) for line in estimates.read_text().splitlines()] if estimates.is_file() else []
    if len(rows) != 1 or len(rows[0].get("veil_rgb", [])) != 3:
        raise CheckFailed(f"murk water estimate {sample.name}: no estimate from the shipped water.npz:\n{proc.stdout}")
    done.append(f"murk water estimate {sample.name}: veil {rows[0]['veil_rgb']} from the shipped water.npz")

    done.append(check_live(murk, env, work, sample, probe["assets"]))
    return done


def check_live(murk: str, env: dict[str, str], work: Path, sample: Path, assets: list[str]) -> str:
    """``murk live`` on ``sample``: the page and its script fetched once, then Ctrl+C (exit 130)."""
    cmd = [murk, "live", str(sample), "--port", "0", "--out", str(work / "live")]
    proc = subprocess.Popen(cmd, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    head = ""
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + STEP_TIMEOUT_S
        while "live view: " not in head and time.monotonic() < deadline and (line := proc.stdout.readline()):
            head += line
        match = re.search(r"live view: (http://127\.0\.0\.1:\d+/)", head)
        if match is None:
            raise CheckFailed(f"murk live printed no address:\n{head}")
        fetched = []
        for name, needle in (("", b"murk live"), ("live.js", b"murkStats"), ("live.css", b"")):
            with urllib.request.urlopen(match[1] + name, timeout=60) as r:
                body = r.read()
            if r.status != 200 or needle not in body:
                raise CheckFailed(f"murk live: GET /{name} answered {r.status} ({len(body)} bytes)")
            fetched.append(f"/{name}")
        proc.send_signal(signal.SIGINT)  # murk live handles Ctrl+C itself, whatever this process inherited
        rest, _ = proc.communicate(timeout=STEP_TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    if proc.returncode != 130:
        raise CheckFailed(f"murk live exited with {proc.returncode} after Ctrl+C, expected 130:\n{head}{rest}")
    if not {"/live.js", "/live.css"} <= set(assets):
        raise CheckFailed(f"murk live's page assets: {assets}")
    return f"murk live {sample.name}: {', '.join(fetched)} served over 127.0.0.1, stopped by Ctrl+C (exit 130)"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", type=Path, help="work in this folder (outside the checkout) and keep it")
    args = ap.parse_args(argv)
    sys.stdout.reconfigure(line_buffering=True)  # type: ignore[union-attr]  # each step's line as it passes
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="murk-wheel-check-") as tmp:
        top = Path(tmp) if args.keep is None else args.keep.resolve()
        if inside(top, ROOT):
            print(f"--keep {top}: expected a folder outside the checkout {ROOT}", file=sys.stderr)
            return 2
        if args.keep is not None:
            shutil.rmtree(top, ignore_errors=True)
        (top / "dist").mkdir(parents=True)
        (top / "work").mkdir()
        try:
            sdist, wheel = build(top / "dist")
            size_mib = wheel.stat().st_size / 2**20
            print(f"built {sdist.name} and {wheel.name} ({size_mib:.1f} MiB), no deprecation warning")
            problems = wheel_problems(wheel, expected_files())
            if problems:
                raise CheckFailed(f"{wheel.name}:\n" + "\n".join(problems))
            print(f"{wheel.name} holds every module, the shipped data, the page assets and the licence files")
            version = wheel.name.split("-")[1]
            python, env = make_env(top / "venv", wheel)
            print(f"installed into a fresh environment {top / 'venv'} (not editable); pip check: ok")
            for line in check_installed(python, env, top / "venv", top / "work", version):
                print(line)
        except (CheckFailed, subprocess.TimeoutExpired) as exc:
            print(f"wheel check FAILED: {exc}", file=sys.stderr)
            return 1
    print(f"wheel check passed in {time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
