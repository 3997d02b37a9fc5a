"""How well a lifter places the Cars the image border cuts: every Car label, by its truncation, the
share whose box lifted from the label's own 2D box (oracle boxes) lies within 3D IoU 0.7 and 0.5,
and the share whose yaw is 30-150 degrees off (length and width swapped). One column per lifted
folder, so a change reads side by side:

    testbed lift --data D --split S --boxes gt --method fit --out LG
    .venv/bin/python benchmarks/lifter_by_truncation.py --data D --split S --lifted LG [--lifted LG2]
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from itertools import pairwise
from pathlib import Path

import numpy as np

from kitti.boxes import wrap_angle
from kitti.dataset import KittiDataset
from kitti.iou import iou_3d
from kitti.labels import read_label

BINS = (0.0, 0.01, 0.15, 0.3, 0.5, 0.7, 1.01)  # KITTI's difficulties stop at 0.15, 0.3 and 0.5


def car_outcomes(data: Path, split: str | None, lifted: Path) -> np.ndarray:
    """Per Car label (N, 3): truncation, 3D IoU of the box lifted from its 2D box (0 if none),
    yaw error (degrees, absolute). An oracle lift writes one box per label box, the same 2D box."""
    ds = KittiDataset(data)
    out = []
    for fid in ds.ids(split):
        path = lifted / f"{fid}.txt"
        lifts = read_label(path) if path.exists() else []
        for g in (o for o in ds.labels(fid) if o.type == "Car"):
            same = [o for o in lifts if np.allclose(o.bbox, g.bbox, atol=0.01)]
            if not same:
                out.append((g.truncated, 0.0, 180.0))
                continue
            iou = float(iou_3d(g.box7[None], same[0].box7[None])[0, 0])
            yaw = abs(np.degrees(float(wrap_angle(same[0].rotation_y - g.rotation_y))))
            out.append((g.truncated, iou, yaw))
    return np.array(out).reshape(-1, 3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--split", default=None, help="ImageSets split (default: every frame)")
    ap.add_argument("--lifted", type=Path, action="append", required=True,
                    help="a folder of boxes lifted from the labels' 2D boxes; repeatable")
    args = ap.parse_args()
    runs = [car_outcomes(args.data, args.split, p) for p in args.lifted]
    head = " | ".join(f"{p}: IoU>=0.7 / >=0.5 / axis off" for p in args.lifted)
    print(f"| truncation | Cars | {head} |")
    print("|---|---:|" + "---|" * len(runs))
    for lo, hi in pairwise(BINS):
        cells = []
        for r in runs:
            m = (r[:, 0] >= lo) & (r[:, 0] < hi)
            off = (r[m, 2] > 30) & (r[m, 2] < 150)
            cells.append(f"{np.mean(r[m, 1] >= 0.7):.2f} / {np.mean(r[m, 1] >= 0.5):.2f} / "
                         f"{np.mean(off):.2f}")
        n = int(((runs[0][:, 0] >= lo) & (runs[0][:, 0] < hi)).sum())
        print(f"| {lo:.2f}-{min(hi, 1.0):.2f} | {n} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
