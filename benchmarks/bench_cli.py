"""How fast the command line answers ``--help``, ``--version`` and usage errors (issue 29, part 6): wall seconds
and CPU seconds (user + sys: on a busy machine the closer estimate of the idle wall time) of a whole
``python -m murk ...`` process per case (medians of ``--repeats`` runs), its exit code, and which heavy modules
(torch, onnxruntime, av, rosbags, ray) it imported. Baseline measured in the same run: the bare
interpreter (``python -c pass``) and the interpreter importing typer + rich (what any typer command pays).

Every case is a usage error or a help/version request, so none does real work; the target is 1 s each on an
idle 2-core machine. The heavy modules are read from ``sys.modules`` at exit (an ``atexit`` hook of the
wrapper that runs ``murk`` as ``python -m murk`` does).

Run:  PYTHONPATH=src python benchmarks/bench_cli.py [--repeats 3] [--only synth] [--markdown] [--before-src DIR]

``--before-src DIR`` times an earlier murk side by side (alternating runs), e.g. the tree before issue 29's
part 6: ``git archive 4ecab2b src | tar -x -C /tmp/before`` then ``--before-src /tmp/before/src``.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import tree_envs

HEAVY = ("torch", "onnxruntime", "av", "rosbags", "ray")

_WRAPPER = (
    "import atexit, runpy, sys\n"
    "def _report():\n"
    f"    heavy = [m for m in {HEAVY!r} if m in sys.modules]\n"
    "    sys.stderr.write('\\nHEAVY=' + ','.join(heavy) + '\\n')\n"
    "atexit.register(_report)\n"
    "sys.argv = ['murk', *sys.argv[1:]]\n"
    "runpy.run_module('murk', run_name='__main__', alter_sys=True)\n"
)


def cases(tmp: Path) -> list[tuple[str, list[str]]]:
    """(label, murk arguments): help, version and one usage error per kind of check of every command."""
    from murk.data import sample_rgbd_dir, sample_underwater_images

    rgbd = str(sample_rgbd_dir())
    img = str(sample_underwater_images()[0])
    missing = str(tmp / "missing")
    out = str(tmp / "out")
    bad_synth = tmp / "synth-bad.yaml"
    bad_synth.write_text("medium:\n  water_typez: [I]\n")
    bad_scene = tmp / "scene-bad.yaml"
    bad_scene.write_text("far_mm: 3\n")
    bad_train = tmp / "train-bad.yaml"
    bad_train.write_text("stepz: 3\n")
    bad_study = tmp / "study-bad.yaml"
    bad_study.write_text("armz: []\n")
    tiny = str(Path(__file__).resolve().parents[1] / "configs" / "train-tiny-cpu.yaml")
    ckpt = tmp / "x.pt"
    ckpt.write_bytes(b"not a checkpoint")
    return [
        ("murk --help", ["--help"]),
        ("murk --version", ["--version"]),
        ("murk nosuchcommand", ["nosuchcommand"]),
        ("synth --help", ["synth", "--help"]),
        ("synth IN OUT --depth-scale 0", ["synth", rgbd, out, "--depth-scale", "0"]),
        ("synth IN OUT --stages basic,foo", ["synth", rgbd, out, "--stages", "basic,foo"]),
        ("synth IN OUT --water-types XX", ["synth", rgbd, out, "--water-types", "XX"]),
        ("synth IN OUT --shard 3/2", ["synth", rgbd, out, "--shard", "3/2"]),
        ("synth IN OUT --format foo", ["synth", rgbd, out, "--format", "foo"]),
        ("synth IN OUT --backend foo", ["synth", rgbd, out, "--backend", "foo"]),
        ("synth IN OUT --config BAD_KEY", ["synth", rgbd, out, "--config", str(bad_synth)]),
        ("synth MISSING OUT", ["synth", missing, out]),
        ("synth --list MISSING OUT", ["synth", "--list", missing, out]),
        ("scenes --help", ["scenes", "--help"]),
        ("scenes OUT --size 0x4", ["scenes", out, "--size", "0x4"]),
        ("scenes OUT --rgb-format gif", ["scenes", out, "--rgb-format", "gif"]),
        ("scenes OUT --config BAD_KEY", ["scenes", out, "--config", str(bad_scene)]),
        ("scenes OUT --textures MISSING", ["scenes", out, "--textures", missing]),
        ("snow extract --help", ["snow", "extract", "--help"]),
        ("snow extract IMG --method foo", ["snow", "extract", img, "--out", f"{out}.npz", "--method", "foo"]),
        ("snow extract IMG --scale x", ["snow", "extract", img, "--out", f"{out}.npz", "--scale", "x"]),
        ("snow extract MISSING", ["snow", "extract", missing, "--out", f"{out}.npz"]),
        ("snow info MISSING", ["snow", "info", f"{missing}.npz"]),
        ("enhance --help", ["enhance", "--help"]),
        ("enhance IMG --method foo", ["enhance", img, "--out", out, "--method", "foo"]),
        ("enhance IMG --method post?lamda=1", ["enhance", img, "--out", out, "--method", "post?lamda=1"]),
        ("enhance IMG --device foo", ["enhance", img, "--out", out, "--device", "foo"]),
        ("enhance IMG -m post --sigma-px -1", ["enhance", img, "--out", out, "-m", "post", "--sigma-px", "-1"]),
        ("enhance MISSING", ["enhance", missing, "--out", out]),
        ("enhance IMG --checkpoint MISSING", ["enhance", img, "--out", out, "-m", "jointid", "--checkpoint", missing]),
        ("eval --help", ["eval", "--help"]),
        ("eval IMG --preset foo", ["eval", img, "--preset", "foo"]),
        ("eval IMG --ssim-window foo", ["eval", img, "--ssim-window", "foo"]),
        ("eval MISSING", ["eval", missing]),
        ("compare --help", ["compare", "--help"]),
        ("compare IMG --method foo", ["compare", img, "--method", "foo", "--out", out]),
        ("compare IMG --uiqm-preset foo", ["compare", img, "--method", "post", "--out", out, "--uiqm-preset", "foo"]),
        ("compare IMG --box bad", ["compare", img, "--method", "post", "--out", out, "--box", "bad"]),
        (
            "compare IMG --method post --method jointd",
            ["compare", img, "--out", out, "--method", "post", "--method", "jointd"],
        ),
        ("compare MISSING", ["compare", missing, "--method", "post", "--out", out]),
        ("study --help", ["study", "--help"]),
        ("study BAD_KEY", ["study", str(bad_study), "--out", out]),
        ("study MISSING", ["study", f"{missing}.yaml", "--out", out]),
        ("train --help", ["train", "--help"]),
        ("train --config BAD_KEY", ["train", "--config", str(bad_train)]),
        ("train --config MISSING", ["train", "--config", f"{missing}.yaml"]),
        ("train --config OK --precision foo", ["train", "--config", tiny, "--precision", "x"]),
        ("train --config OK --data MISSING", ["train", "--config", tiny, "--data", missing, "--out", out]),
        ("export --help", ["export", "--help"]),
        ("export --model foo", ["export", "-c", str(ckpt), "-o", f"{out}.onnx", "--model", "foo"]),
        ("export --size 0x0", ["export", "-c", str(ckpt), "-o", f"{out}.onnx", "--size", "0x0"]),
        ("export -c MISSING", ["export", "-c", f"{missing}.pt", "-o", f"{out}.onnx"]),
        ("export -c NOT_A_CHECKPOINT (needs torch)", ["export", "-c", str(ckpt), "-o", f"{out}.onnx"]),
        ("demo --help", ["demo", "--help"]),
        ("demo --seed x", ["demo", "--seed", "x"]),
    ]


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_once(args: list[str], env: dict[str, str]) -> tuple[float, float, int, str, str]:
    """Wall seconds, CPU seconds (user + sys), exit code, heavy modules imported, first stderr line."""
    cpu0 = _children_cpu_s()
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _WRAPPER, *args], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    cpu = _children_cpu_s() - cpu0
    lines = proc.stderr.strip().splitlines()
    heavy = next((ln[6:] for ln in reversed(lines) if ln.startswith("HEAVY=")), "?")
    message = next((ln for ln in lines if ln.strip() and not ln.startswith("HEAVY=")), "")
    return wall, cpu, proc.returncode, heavy or "-", message.strip()[:70]


def baseline_s(code: str, repeats: int, env: dict[str, str]) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True, env=env)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--only", default="", help="Run only the cases whose label contains this text.")
    ap.add_argument("--markdown", action="store_true", help="Print a Markdown table.")
    ap.add_argument(
        "--before-src",
        type=Path,
        default=None,
        help="The src/ folder of an earlier murk (e.g. from 'git archive REV src'): every case also runs with it, "
        "in alternating runs, and both medians are printed side by side.",
    )
    args = ap.parse_args()
    trees = tree_envs(args.before_src, warm="murk.cli.main")  # .pyc files compiled first: no case pays for it
    env = trees["now"]
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        todo = [c for c in cases(tmp) if args.only in c[0]]
        bare = baseline_s("pass", args.repeats, env)
        typer_s = baseline_s("import typer, rich.console", args.repeats, env)
        print(f"baseline: python -c pass {bare:.2f} s; import typer + rich {typer_s:.2f} s ({args.repeats} runs each)")
        names = list(trees)
        if args.markdown:
            cols = " | ".join(f"{n}: wall s | {n}: CPU s | {n}: heavy imports" for n in names)
            print(f"| case | {cols} | exit | message |\n|---|{'---:|---:|---|' * len(names)}---:|---|")
        worst = dict.fromkeys(names, 0.0)
        for label, murk_args in todo:
            runs: dict[str, list[tuple[float, float, int, str, str]]] = {n: [] for n in names}
            for _ in range(args.repeats):
                for n in names:
                    runs[n].append(run_once(murk_args, trees[n]))
            wall = {n: statistics.median(r[0] for r in runs[n]) for n in names}
            cpu = {n: statistics.median(r[1] for r in runs[n]) for n in names}
            heavy = {n: runs[n][-1][3] for n in names}
            _, _, code, _, message = runs["now"][-1]
            for n in names:
                worst[n] = max(worst[n], wall[n])
            if args.markdown:
                cells = " | ".join(f"{wall[n]:.2f} | {cpu[n]:.2f} | {heavy[n]}" for n in names)
                print(f"| `{label}` | {cells} | {code} | {message.replace('|', '/')} |")
            else:
                cells = "  ".join(f"{n} {wall[n]:5.2f} s (CPU {cpu[n]:4.2f} s) heavy: {heavy[n]:<6}" for n in names)
                print(f"{label:<40} {cells}  exit {code}  {message}")
        slowest = ", ".join(f"{n} {worst[n]:.2f} s" for n in names)
        print(f"slowest case: {slowest} (target 1 s on an idle 2-core machine)")


if __name__ == "__main__":
    main()
