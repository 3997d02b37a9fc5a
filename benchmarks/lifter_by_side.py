"""Lifted Cars by lateral position: on a crowned road the half left of the ego lane falls away, so
each lifter's accuracy is split by the label's camera x (left negative). Moderate-like cars
(occlusion <= 1, truncation <= 0.3, 2D height >= 25 px) of a KITTI root against one result folder:
share within 3D IoU 0.7, median height error (dy, m) and along-ray depth error (m).

    .venv/bin/python benchmarks/lifter_by_side.py --data data/lifter/urban_val \
        --pred runs/lifter/gen_net/64_fit --pred runs/lifter/gen_net/64_mono
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from kitti.dataset import KittiDataset
from kitti.eval.protocol import outside_difficulty
from kitti.iou import iou_3d
from kitti.labels import read_label

MODERATE = 1  # kitti.eval.protocol's difficulty index
BINS = ((-30.0, -6.0), (-6.0, -2.0), (-2.0, 2.0), (2.0, 30.0))  # camera x (m), left negative


def rows(ds: KittiDataset, pred: Path) -> np.ndarray:
    """(x, IoU, dy, ddepth) per moderate-like labelled Car; an unmatched one has IoU 0."""
    out = []
    for fid in ds.ids():
        preds = read_label(pred / f"{fid}.txt")
        for o in ds.labels(fid):
            if o.type != "Car" or outside_difficulty(o.bbox[3] - o.bbox[1], o.occluded,
                                                   o.truncated, MODERATE):
                continue
            m = [p for p in preds if np.allclose(p.bbox, o.bbox, atol=1e-2)]
            if not m:
                out.append((o.box7[0], 0.0, np.nan, np.nan))
                continue
            b = m[0].box7
            out.append((o.box7[0], iou_3d(o.box7, b)[0, 0], b[1] - o.box7[1],
                        np.hypot(b[0], b[2]) - np.hypot(o.box7[0], o.box7[2])))
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--pred", action="append", required=True)
    args = ap.parse_args()
    ds = KittiDataset(args.data)
    print("| result | camera x (m) | cars | IoU >= 0.7 | median dy (m) | median depth error (m) |")
    print("|---|---|---|---|---|---|")
    for pred in args.pred:
        r = rows(ds, Path(pred))
        for lo, hi in BINS:
            m = (r[:, 0] >= lo) & (r[:, 0] < hi)
            print(f"| {pred} | {lo:+.0f} to {hi:+.0f} | {m.sum()} | {np.mean(r[m, 1] >= 0.7):.2f} "
                  f"| {np.nanmedian(r[m, 2]):+.3f} | {np.nanmedian(r[m, 3]):+.2f} |")


if __name__ == "__main__":
    main()
