"""How each class's 2D label box sits on the projection of its own 3D box, generated against real.

KITTI's object devkit: annotators placed 3D boxes in the point clouds, and since a fixed-size box
fits a pedestrian badly, each pedestrian's left and right boundaries were labelled again in the
image (Mechanical Turk). Every other class's 2D box is the projection of its 3D box. The generator
follows that (`simgen.labels`, `LabelRules.silhouette_sides`). This script prints, per class, over
the untruncated labels of each KITTI root: the label box's width over the projected box's width
(median, 10th and 90th percentile) and the median distance of its top and bottom from the
projected box's, in pixels.

    .venv/bin/python benchmarks/box_sides.py --data data/fidelity/urban200_sides \
        --data ../shared/kitti_real_dev
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.boxes import project_boxes
from kitti.dataset import KittiDataset

CLASSES = ("Car", "Van", "Truck", "Pedestrian", "Cyclist")


def sides(root: Path) -> dict[str, np.ndarray]:
    """Per class, rows of (width ratio, |top gap| px, |bottom gap| px) of every untruncated label."""
    ds = KittiDataset(root)
    rows: dict[str, list] = {c: [] for c in CLASSES}
    for fid in tqdm(ds.ids(), desc=f"{root}", leave=False):
        objs = [o for o in ds.labels(fid) if o.type in CLASSES and o.truncated == 0]
        if not objs:
            continue
        proj = project_boxes(np.stack([o.box7 for o in objs]), ds.calib(fid), ds.image_size(fid))
        for o, p in zip(objs, proj):
            rows[o.type].append(((o.bbox[2] - o.bbox[0]) / (p[2] - p[0]), abs(o.bbox[1] - p[1]),
                                 abs(o.bbox[3] - p[3])))
    return {c: np.array(r, dtype=float).reshape(-1, 3) for c, r in rows.items()}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, action="append", required=True, help="a KITTI root (repeat)")
    args = ap.parse_args(argv)
    print("| data | class | untruncated labels | width / projected width: median (p10, p90) "
          "| median top / bottom gap (px) |")
    print("|---|---|---|---|---|")
    for root in args.data:
        for c, r in sides(root).items():
            if not len(r):
                continue
            q10, q50, q90 = np.percentile(r[:, 0], [10, 50, 90])
            print(f"| {root} | {c} | {len(r)} | {q50:.3f} ({q10:.3f}, {q90:.3f}) | "
                  f"{np.median(r[:, 1]):.2f} / {np.median(r[:, 2]):.2f} |")


if __name__ == "__main__":
    main()
