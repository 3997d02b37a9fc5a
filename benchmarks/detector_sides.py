"""How far a detector's left and right box sides lie from the labels', per class (the figures
`testbed lift --side-sd` and `--side-dof` take, by which `fit` then weighs a detected box's sides).

Each detection scoring at least `fit`'s CLAIM_MIN_SCORE is matched to the label of its class (a
Car to a Car or Van, a Pedestrian to a Pedestrian or Person_sitting) it overlaps most, at 2D IoU
0.5 or more (each label taken once, best score first); a side counts where neither box touches
the image border there. Prints, per class, the side errors' mean, root mean square (the sd a
least-squares weight takes), robust sd (1.4826 x the median absolute deviation) and percentiles,
left and right pooled, then top and bottom; and the Student-t centred on 0 that fits the left and
right errors best (maximum likelihood: its scale and degrees of freedom, `--side-sd` and
`--side-dof`).

    testbed detect --data D --split val --out P
    .venv/bin/python benchmarks/detector_sides.py --data D --split val --pred P
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import numpy as np
from scipy import stats

from kitti.dataset import KittiDataset
from kitti.iou import iou_2d
from kitti.labels import read_label
from lifter.fit import CLAIM_MIN_SCORE
from lifter.placement import BORDER_LEFT, BORDER_RIGHT

MATCH_IOU = 0.5
LABELS = {"Car": ("Car", "Van"), "Pedestrian": ("Pedestrian", "Person_sitting"), "Cyclist": ("Cyclist",)}


def side_errors(data: Path, split: str | None, pred: Path, cls: str) -> tuple[np.ndarray, np.ndarray]:
    """(left/right errors, top/bottom errors) in px, detection minus label, of the matched boxes
    of class `cls`."""
    ds = KittiDataset(data)
    lr, tb = [], []
    for fid in ds.ids(split):
        width = ds.image_size(fid)[0]
        gt = [o.bbox for o in ds.labels(fid) if o.type in LABELS[cls]]
        path = pred / f"{fid}.txt"
        det = sorted((o for o in (read_label(path) if path.exists() else [])
                      if o.type == cls and o.score >= CLAIM_MIN_SCORE), key=lambda o: -o.score)
        if not gt or not det:
            continue
        iou = iou_2d(np.array([o.bbox for o in det]), np.array(gt))
        free = np.ones(len(gt), bool)
        for i, o in enumerate(det):
            j = int(np.argmax(np.where(free, iou[i], -1.0)))
            if not free[j] or iou[i, j] < MATCH_IOU:
                continue
            free[j] = False
            d, g = o.bbox, gt[j]
            if min(d[0], g[0]) > BORDER_LEFT:
                lr.append(d[0] - g[0])
            if max(d[2], g[2]) < width - BORDER_RIGHT:
                lr.append(d[2] - g[2])
            tb += [d[1] - g[1], d[3] - g[3]]
    return np.array(lr), np.array(tb)


def describe(name: str, e: np.ndarray) -> str:
    med = np.median(e)
    q = np.percentile(np.abs(e), [50, 90, 99])
    return (f"{name:>16}: n {len(e):5d}  mean {e.mean():+6.2f}  rms {np.sqrt(np.mean(e ** 2)):6.2f}  "
            f"robust sd {1.4826 * np.median(np.abs(e - med)):5.2f}  |e| 50/90/99 % "
            f"{q[0]:5.2f} / {q[1]:5.2f} / {q[2]:5.2f} px")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="KITTI-format root with labels")
    ap.add_argument("--split", default=None, help="ImageSets name (default: every frame)")
    ap.add_argument("--pred", type=Path, required=True, help="detection files (testbed detect)")
    args = ap.parse_args()
    print(f"detections scoring >= {CLAIM_MIN_SCORE}, matched to a label of their class at 2D IoU >= "
          f"{MATCH_IOU}:")
    for cls, names in LABELS.items():
        lr, tb = side_errors(args.data, args.split, args.pred, cls)
        print(f"{cls} (labels {', '.join(names)})")
        print(describe("left and right", lr))
        print(describe("top and bottom", tb))
        if len(lr) >= 2:
            dof, _, scale = stats.t.fit(lr, floc=0.0)
            dofs = f"{dof:.2f} degrees of freedom" if dof < 1e3 else "Gaussian (no heavier tails)"
            print(f"{'Student-t fit':>16}: left and right errors, scale {scale:.2f} px, {dofs}")


if __name__ == "__main__":
    main()
