"""Where the whole chain loses the Cars a lifter places from their labels' boxes: every moderate Car,
its best detection (score >= `fit`'s CLAIM_MIN_SCORE, the highest 2D IoU), the 3D IoU of the box
lifted from that detection and of the box lifted from the Car's own label box.

Prints, by the detection's 2D IoU, how many Cars each lift puts within 3D IoU 0.7 and the median
side errors of the detections; then, for the Cars the label's box lifts within 0.7 and the detected
box does not, the median error of each box component from both lifts (what the detected box costs).

    testbed detect --data D --split S --out P
    testbed lift --data D --split S --boxes P --method fit --out LP
    testbed lift --data D --split S --boxes gt --method fit --out LG
    .venv/bin/python benchmarks/chain_losses.py --data D --split S --pred P --lifted LP --oracle LG
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from itertools import pairwise
from pathlib import Path

import numpy as np

from kitti.boxes import wrap_angle
from kitti.dataset import KittiDataset
from kitti.iou import iou_2d, iou_3d
from kitti.labels import Object3D, read_label
from lifter.fit import CLAIM_MIN_SCORE

BINS = (0.0, 0.5, 0.7, 0.8, 0.9, 1.01)
COMPONENTS = ("x", "y", "z", "h", "w", "l", "yaw deg")


def moderate(o: Object3D) -> bool:
    """KITTI's moderate Car: 25 px tall or more, at most partly occluded, truncated 0.3 or less."""
    return o.type == "Car" and o.height_px >= 25 and o.occluded <= 1 and o.truncated <= 0.3


def errors(a: Object3D, g: Object3D) -> np.ndarray:
    """Lifted minus true: location, size and yaw (degrees, wrapped)."""
    return np.array([*(a.location - g.location), a.h - g.h, a.w - g.w, a.l - g.l,
                     np.degrees(float(wrap_angle(a.rotation_y - g.rotation_y)))])


def rows(data: Path, split: str | None, pred: Path, lifted: Path, oracle: Path) -> list[dict]:
    """One row per moderate Car: its best detection's 2D IoU and side errors, both lifts' 3D IoU
    and errors. The lifted files hold one box per detection, in the detection file's order."""
    ds = KittiDataset(data)
    out = []
    for fid in ds.ids(split):
        dets = read_label(pred / f"{fid}.txt") if (pred / f"{fid}.txt").exists() else []
        lifts = read_label(lifted / f"{fid}.txt") if dets else []
        keep = [i for i, d in enumerate(dets) if d.type == "Car" and d.score >= CLAIM_MIN_SCORE]
        oracles = [o for o in read_label(oracle / f"{fid}.txt") if o.type == "Car"]
        for g in (o for o in ds.labels(fid) if moderate(o)):
            r = {"iou2": 0.0, "iou3": 0.0, "iou3_oracle": 0.0}
            if keep:
                iou = iou_2d(g.bbox[None], np.array([dets[i].bbox for i in keep]))[0]
                k = keep[int(np.argmax(iou))]
                r.update(iou2=float(iou.max()), side=dets[k].bbox - g.bbox,
                         iou3=float(iou_3d(g.box7[None], lifts[k].box7[None])[0, 0]),
                         err=errors(lifts[k], g))
            if oracles:  # the label's own box: the lift whose 2D box is the label's
                k = int(np.argmax(iou_2d(g.bbox[None], np.array([o.bbox for o in oracles]))[0]))
                r.update(iou3_oracle=float(iou_3d(g.box7[None], oracles[k].box7[None])[0, 0]),
                         err_oracle=errors(oracles[k], g))
            out.append(r)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="KITTI-format root with labels")
    ap.add_argument("--split", default=None, help="ImageSets name (default: every frame)")
    ap.add_argument("--pred", type=Path, required=True, help="the detections (testbed detect)")
    ap.add_argument("--lifted", type=Path, required=True, help="fit on those detections")
    ap.add_argument("--oracle", type=Path, required=True, help="fit on the label boxes (--boxes gt)")
    args = ap.parse_args()
    rs = rows(args.data, args.split, args.pred, args.lifted, args.oracle)
    print(f"{len(rs)} moderate Cars; best detection scoring >= {CLAIM_MIN_SCORE}")
    print("| detection's 2D IoU | Cars | within 3D 0.7: from the detection | from the label box | "
          "median abs side error L / T / R / B px |")
    print("|---|---:|---:|---:|---|")
    iou2 = np.array([r["iou2"] for r in rs])
    for lo, hi in pairwise(BINS):
        m = np.flatnonzero((iou2 >= lo) & (iou2 < hi))
        if not len(m):
            continue
        side = np.array([rs[i].get("side", np.full(4, np.nan)) for i in m])
        print(f"| {lo:.1f}-{min(hi, 1.0):.1f} | {len(m)} | {np.mean([rs[i]['iou3'] >= 0.7 for i in m]):.2f} | "
              f"{np.mean([rs[i]['iou3_oracle'] >= 0.7 for i in m]):.2f} | "
              + " / ".join(f"{v:.1f}" for v in np.nanmedian(np.abs(side), axis=0)) + " |")
    both = [r for r in rs if r["iou2"] >= 0.7 and r["iou3_oracle"] >= 0.7]
    lost = [r for r in both if r["iou3"] < 0.7]
    print(f"\nof {len(both)} Cars detected at 2D IoU >= 0.7 and lifted within 3D 0.7 from their label "
          f"box, {len(lost)} are not from the detection; their median abs error:")
    print("| lifted from | " + " | ".join(COMPONENTS) + " |")
    print("|---|" + "---:|" * len(COMPONENTS))
    for name, key in (("the detection", "err"), ("the label box", "err_oracle")):
        med = np.median(np.abs([r[key] for r in lost]), axis=0) if lost else np.full(7, np.nan)
        print(f"| {name} | " + " | ".join(f"{v:.2f}" for v in med) + " |")


if __name__ == "__main__":
    main()
