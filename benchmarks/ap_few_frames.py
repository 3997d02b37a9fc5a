"""What a few frames say about a detector's AP|R40: small sets drawn (without replacement) from a
large labelled set, each scored by the devkit and on the measured recall (`kitti.eval.ap`,
`Curve.r40_measured`), against the devkit's figure on the whole set. Made for the real dev
frames' question: 11 frames holding 14 moderate Cars, where the devkit's AP|R40 cannot exceed
32.5, while a target such as 40 is a figure on a set large enough not to cap it.

    .venv/bin/python benchmarks/ap_few_frames.py --gt ROOT/training/label_2 \\
        --split ROOT/ImageSets/trainval.txt --pred DETECTIONS \\
        [--frames 11] [--sets 300] [--classes Car]

Prints, per class and difficulty, the whole set's devkit figure, then over the drawn sets the
mean and the 2.5 / 50 / 97.5 percentiles of each small-set figure, the mean truth boxes a set
holds, and the share of sets whose measured figure falls below the whole set's by more than 10.
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.eval.annotations import load_annotations
from kitti.eval.evaluate import evaluate
from kitti.splits import read_split

SEED = 20261129


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--gt", type=Path, required=True, help="label_2 folder with the truth")
    parser.add_argument("--split", type=Path, required=True, help="ImageSets file of the frames")
    parser.add_argument("--pred", type=Path, required=True, help="result folder")
    parser.add_argument("--frames", type=int, default=11, help="frames in each drawn set")
    parser.add_argument("--sets", type=int, default=300, help="sets drawn")
    parser.add_argument("--classes", default="Car")
    args = parser.parse_args()
    for path, what in ((args.split, "--split"), (args.gt, "--gt"), (args.pred, "--pred")):
        if not path.exists():
            raise SystemExit(f"{what} {path}: no such file or folder")
    ids = read_split(args.split)
    if not 0 < args.frames < len(ids):
        raise SystemExit(f"--frames {args.frames}: must lie between 1 and {len(ids) - 1}")
    classes = args.classes.split(",")
    gt, dt = load_annotations(args.gt, ids), load_annotations(args.pred, ids, missing_ok=True)
    whole = evaluate(gt, dt, classes=classes, metrics=["2d"])
    rng = np.random.default_rng(SEED)
    rows = {c: [] for c in classes}  # per set: (devkit [3], measured [3], n_gt [3])
    for _ in tqdm(range(args.sets), desc="sets"):
        pick = sorted(rng.choice(len(ids), args.frames, replace=False))
        sub = [ids[i] for i in pick]
        res = evaluate({k: gt[k] for k in sub}, {k: dt[k] for k in sub if k in dt}, classes=classes,
                       metrics=["2d"])
        for c in classes:
            rows[c].append((res.ap[c]["2d"]["R40"], res.measured[c]["strict"]["2d"], res.n_gt[c]))
    print(f"{args.sets} sets of {args.frames} frames drawn from the {len(ids)} of {args.split} "
          f"(seed {SEED}); 2D AP|R40\n")
    print("| class | difficulty | whole set (devkit) | truth boxes a set (mean) | devkit on a set: mean "
          "[2.5, 50, 97.5 %] | measured recall on a set: mean [2.5, 50, 97.5 %] | sets measured > 10 "
          "below the whole |")
    print("|---|---|---|---|---|---|---|")
    for c in classes:
        a = np.array(rows[c], dtype=float)  # (sets, 3, 3)
        for d, name in enumerate(("easy", "moderate", "hard")):
            full = whole.ap[c]["2d"]["R40"][d]
            cells = []
            for k in (0, 1):
                v = a[:, k, d]
                q = np.percentile(v, [2.5, 50, 97.5])
                cells.append(f"{v.mean():.1f} [{q[0]:.1f}, {q[1]:.1f}, {q[2]:.1f}]")
            low = float(np.mean(a[:, 1, d] < full - 10))
            print(f"| {c} | {name} | {full:.1f} | {a[:, 2, d].mean():.1f} | {cells[0]} | {cells[1]} | "
                  f"{low:.0%} |")


if __name__ == "__main__":
    main()
