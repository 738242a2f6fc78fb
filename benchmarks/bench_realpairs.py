"""Real-water quality on real paired underwater photographs: PSNR, SSIM and CIEDE2000 against the references.

Run: PYTHONPATH=src python benchmarks/bench_realpairs.py --pairs DIR [--out OUT] [--max-side 256]
     [--methods raw greyworld+clahe "paper=jointid+post?preset=paper" "mine=jointid:runs/x/best.pt" ...]

DIR holds ``input/`` and ``reference/`` (matched by file stem), or subfolders that each do (one set each,
e.g. the development set ``realpairs_dev/{uieb18,uimnet9}``). murk ships no real pairs: pass the folder. Every
method runs through ``murk compare --ref`` (the same code as the command) at a long side of ``--max-side``;
the table gives per set the mean PSNR / SSIM / CIEDE2000 and the paired PSNR difference to the raw input,
then the mean over sets (each set counted once). The per-image numbers are in ``OUT/<set>/metrics.csv``.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import torch

from murk.report.methods import parse_method
from murk.report.study import evaluate_real_pairs

DEFAULT_METHODS = (
    "raw",
    "greyworld+clahe",
    "udcp",
    "post",
    "post(paper)=post?preset=paper",
    "jointid",
    "jointid+post",
    "jointid+post(paper)=jointid+post?preset=paper",
    "lite",
    "lite+post",
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", required=True, type=Path, help="folder of input/ + reference/, or of such sets")
    ap.add_argument("--methods", nargs="+", default=list(DEFAULT_METHODS), help="method specs (murk compare)")
    ap.add_argument("--max-side", type=int, default=256)
    ap.add_argument("--out", type=Path, default=None, help="report folder (default: a temporary one)")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    methods = [parse_method(m) for m in args.methods]  # LABEL=SPEC names a method with options
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        res = evaluate_real_pairs(args.pairs, methods, out, max_side=args.max_side, on_event=print)
    sets = res["sets"]
    head = " | ".join(f"{name} ({s['images']}) PSNR / dPSNR / SSIM / CIEDE2000" for name, s in sets.items())
    print(f"\n| method | {head} | mean over sets PSNR / SSIM / CIEDE2000 |")
    print("|---|" + "---|" * (len(sets) + 1))
    for m in res["methods"]:
        cells = []
        for s in sets.values():
            r = s["summary"][m]
            cells.append(
                f"{r['psnr']['mean']:.2f} / {r['d_psnr']['mean']:+.2f} / {r['ssim']['mean']:.3f} / "
                f"{r['ciede2000']['mean']:.2f}"
            )
        o = res["mean_over_sets"][m]
        print(f"| `{m}` | " + " | ".join(cells) + f" | {o['psnr']:.2f} / {o['ssim']:.3f} / {o['ciede2000']:.2f} |")


if __name__ == "__main__":
    main()
