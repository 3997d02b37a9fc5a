"""Where a detector finds and misses KITTI-moderate Cars, by the 2D box height (a diagnosis).

For every Car label that the official protocol evaluates at moderate (height >= 25 px, occlusion
<= 1, truncation <= 0.30), the best 2D IoU with any Car detection scoring >= --score; a label counts
as found at IoU 0.7 (the official Car match). Labels are binned by box height, so a weight file's
loss on a generator's held-out frames can be read against the heights real labels have. Beside it,
the Car detections at --score that overlap no label of any type at IoU 0.5, per frame.

    .venv/bin/python benchmarks/detector_by_height.py --data ROOT [--split FILE] \
        --pred A=DETECTIONS_A --pred B=DETECTIONS_B [--score 0.3]
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import numpy as np

from kitti.eval.annotations import load_annotations
from kitti.eval.protocol import outside_difficulty
from kitti.iou import iou_2d
from kitti.splits import read_split

EDGES = (25, 40, 60, 100, np.inf)  # px; 25 and 40 are the devkit's moderate and easy minimum heights
MATCH_IOU, FP_IOU = 0.7, 0.5


def by_height(gt: dict, pred: dict, score: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Moderate Car labels per height bin, the share of them found at IoU 0.7, and the unmatched
    Car detections per frame."""
    n, found, fps = np.zeros(len(EDGES) - 1, int), np.zeros(len(EDGES) - 1, int), []
    for fid, labels in gt.items():
        dets = np.array([d.bbox for d in pred.get(fid, []) if d.type == "Car" and d.score >= score]).reshape(-1, 4)
        every = np.array([o.bbox for o in labels]).reshape(-1, 4)
        fps.append(int((iou_2d(dets, every).max(axis=1, initial=0.0) < FP_IOU).sum()))
        for o in labels:
            h = o.bbox[3] - o.bbox[1]
            if o.type != "Car" or outside_difficulty(h, o.occluded, o.truncated, 1):
                continue
            k = int(np.searchsorted(EDGES, h, side="right")) - 1
            n[k] += 1
            found[k] += iou_2d(np.array(o.bbox), dets).max(initial=0.0) >= MATCH_IOU
    return n, found / np.maximum(n, 1), float(np.mean(fps))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, type=Path, help="KITTI root with training/label_2")
    ap.add_argument("--split", type=Path, help="ImageSets file [default: every label file]")
    ap.add_argument("--pred", required=True, action="append", help="NAME=DIR of KITTI result files")
    ap.add_argument("--score", type=float, default=0.3)
    args = ap.parse_args()
    bins = [f"{lo:g}-{hi:g} px" if np.isfinite(hi) else f">= {lo:g} px" for lo, hi in zip(EDGES, EDGES[1:])]
    print(f"{args.data}: moderate Cars found at 2D IoU {MATCH_IOU} by a Car detection scoring >= {args.score}, "
          "by box height\n")
    print("| weights | " + " | ".join(bins) + " | unmatched Car detections a frame |")
    print("|---" * (len(bins) + 2) + "|")
    gt = load_annotations(args.data / "training" / "label_2", read_split(args.split) if args.split else None)
    if not gt:
        raise SystemExit(f"{args.data / 'training' / 'label_2'}: no label files (split {args.split})")
    for item in args.pred:
        name, _, folder = item.partition("=")
        if not folder:
            raise SystemExit(f"--pred {item!r}: expected NAME=DIR")
        n, share, fp = by_height(gt, load_annotations(folder, list(gt), missing_ok=True), args.score)
        print(f"| {name} | " + " | ".join(f"{100 * s:.1f} %" for s in share) + f" | {fp:.2f} |")
    print("| labels | " + " | ".join(str(c) for c in n) + " | |")


if __name__ == "__main__":
    main()
