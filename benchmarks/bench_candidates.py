"""Candidate weights side by side on the real-water instruments (issue 27): one table row per checkpoint.

Every row gives:
- the real pairs: the mean over sets of PSNR / SSIM / CIEDE2000 and each set's PSNR;
- the paired PSNR difference to the first candidate over all images: mean +- sd, images higher, paired t;
- the marine-snow residue on snowy/snow-free pairs (``murk compare --snow-clean``);
- the held-out PSNR gain on the photographic held-out scenes of ``bench_model.py``;
- the periodic-artefact ratio on the 13 shipped real images.

These are the figures of the candidate tables in docs/train.md. Candidates are scored as networks, as `murk study`
scores its arms: `jointid` without its `refine` step and `lite` blend (``murk.report.study.ARM_OPTIONS``). The
first candidate is the baseline, e.g. the shipped weights. Keep it first, so that the paired column reads "this
candidate minus the shipped one".

Run: PYTHONPATH=src python benchmarks/bench_candidates.py --method jointid --pairs DIR [--snow-pairs DIR]
     [--scenes 64] [--threads 1] [--json FILE] shipped=SHIPPED run7=runs/x/latest.pt ...
(``DIR`` as in ``bench_realpairs.py``. ``--snow-pairs`` is a folder with ``snowy/`` and ``clean/``, matched by file
stem. A candidate ``shipped`` with no path is the shipped weights of ``--method``.)

A warning that goes with every such table: picking the best of many checkpoints on these same 27 development
pairs and 64 scenes overstates the winner. Checkpoints of one run differed by up to 0.4 dB on the development set
(docs/train.md, "`lite` stage 4 continued"), and the 64-scene figures run 0.16-0.56 dB above those of 256 scenes
(``--scenes 256``; BENCHMARKS.md, "Real water").
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import torch
from bench_model import heldout_scenes, real_measures

from murk.data import shipped_jointid_weights, shipped_lite_weights
from murk.enhance.restorer import create
from murk.io.images import list_images
from murk.report.compare import run_compare
from murk.report.heldout import score_heldout
from murk.report.methods import parse_method
from murk.report.study import arm_spec, evaluate_real_pairs

SNOW_KEYS = ("snow_residue", "snow_sites_left", "snow_free_gms", "snow_colour_residue")


def candidates(specs: list[str], method: str) -> dict[str, str]:
    """``{label: checkpoint}`` from ``LABEL=PATH``, ``PATH`` (labelled by its file name) or ``shipped``."""
    out: dict[str, str] = {}
    for spec in specs:
        label, sep, path = spec.partition("=")
        if not sep:
            label, path = (spec, "") if spec == "shipped" else (Path(spec).stem, spec)
        if not path and label == "shipped":
            path = str(shipped_jointid_weights() if method == "jointid" else shipped_lite_weights())
        if not Path(path).is_file():
            raise SystemExit(f"candidate {label!r}: no checkpoint file at {path!r}")
        if label in out:
            raise SystemExit(f"candidate {label!r} is given twice")
        out[label] = path
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("candidates", nargs="+", help="LABEL=CHECKPOINT, CHECKPOINT or shipped; the first is the baseline")
    ap.add_argument("--method", choices=["jointid", "lite"], default="jointid")
    ap.add_argument("--pairs", required=True, type=Path, help="real pairs: input/ + reference/, or sets of them")
    ap.add_argument("--snow-pairs", type=Path, default=None, help="folder of snowy/ and clean/ (matched by stem)")
    ap.add_argument("--scenes", type=int, default=64, help="photographic held-out scenes (bench_model.py)")
    ap.add_argument("--max-side", type=int, default=256)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--json", type=Path, default=None, help="also write every figure to this JSON file")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cands = candidates(args.candidates, args.method)
    labels = list(cands)
    # Candidates are networks: scored as trained, as the study scores its arms (jointid without refine or lite blend)
    methods = [parse_method(arm_spec(args.method, f"{lab}={args.method}:{path}")) for lab, path in cands.items()]
    figures: dict[str, dict[str, object]] = {lab: {"checkpoint": path} for lab, path in cands.items()}

    with tempfile.TemporaryDirectory() as tmp:
        contrasts = [(lab, labels[0]) for lab in labels[1:]]
        real = evaluate_real_pairs(
            args.pairs, methods, Path(tmp) / "pairs", max_side=args.max_side, contrasts=contrasts
        )
        snow = None
        if args.snow_pairs is not None:
            if not (args.snow_pairs / "snowy").is_dir() or not (args.snow_pairs / "clean").is_dir():
                raise SystemExit(f"--snow-pairs: {args.snow_pairs} must hold snowy/ and clean/ folders")
            snow = run_compare(
                list_images(args.snow_pairs / "snowy"),
                methods,
                Path(tmp) / "snow",
                snow_clean=args.snow_pairs / "clean",
                title="bench_candidates: marine snow",
            ).summary

    data = heldout_scenes(args.scenes, 0.5)
    restorers = {lab: create(arm_spec(args.method, args.method), checkpoint=path) for lab, path in cands.items()}
    held = score_heldout(data, restorers)
    paired = {c["a"]: c["psnr"] for c in real["contrasts"]}

    sets = list(real["sets"])
    print(
        f"\n{args.method}: real pairs {args.pairs} (long side {args.max_side}), paired against `{labels[0]}`; "
        f"held-out: {args.scenes} photographic scenes, 320x240, input {held['input']['psnr']:.2f} dB"
    )
    head = " / ".join(sets)
    print(
        f"| weights | real pairs, mean over sets | {head} PSNR | paired dPSNR vs `{labels[0]}` | held-out gain "
        "| snow residue / sites left / GMS away / colour residue | periodic artefacts |"
    )
    print("|---|---|---|---|---|---|---|")
    for lab in labels:
        o = real["mean_over_sets"][lab]
        per_set = " / ".join(f"{real['sets'][s]['summary'][lab]['psnr']['mean']:.2f}" for s in sets)
        c = paired.get(lab)
        pair_cell = f"{c['mean']:+.2f} +- {c['std']:.2f}, higher on {c['higher']}/{c['n']}, t {c['t']:.2f}" if c else ""
        gain = held[lab]["psnr"] - held["input"]["psnr"]
        snow_cell = ""
        if snow is not None:
            s = {k: snow[lab][k]["mean"] for k in SNOW_KEYS}
            snow_cell = " / ".join(f"{s[k]:.3f}" for k in SNOW_KEYS)
        art = real_measures(restorers[lab])
        print(
            f"| `{lab}` | {o['psnr']:.2f} / {o['ssim']:.3f} / {o['ciede2000']:.2f} | {per_set} | {pair_cell} "
            f"| {gain:+.2f} | {snow_cell} | {art['artefact_periodic_ratio']:.3f}x |"
        )
        figures[lab].update(
            real_mean_over_sets=o,
            real_per_set_psnr={s: real["sets"][s]["summary"][lab]["psnr"]["mean"] for s in sets},
            paired_psnr_vs_first=c,
            heldout_gain_db=gain,
            snow=None if snow is None else {k: snow[lab][k]["mean"] for k in SNOW_KEYS},
            real_images=art,
        )
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
