"""How each class's 2D label box sits on the projection of its own 3D box, generated against real.

KITTI's object devkit: annotators placed 3D boxes in the Velodyne point clouds (yaw-only boxes in
that frame), and since a fixed-size box fits a pedestrian badly, each pedestrian's left and right
boundaries were labelled again in the image (Mechanical Turk). label_2 states each 3D box with a
yaw about camera y only, so two projections can be compared with the 2D box: the label box's own
("camera") and the same box stood upright in the LiDAR's frame ("lidar",
`kitti.boxes.lidar_upright_corners`). Per class, over the untruncated labels of each KITTI root:
the median of the largest side difference (px) to either projection, the label box's width over
the LiDAR-upright projection's (median, 10th and 90th percentile), and the share of labels whose
bottom lies more than 0.1 px above the camera projection's.

    .venv/bin/python benchmarks/box_sides.py --data data/fidelity/urban200_kitti2d \
        --data ../shared/kitti_real_dev
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from testbed.fidelity.labels import box_projections

CLASSES = ("Car", "Van", "Truck", "Pedestrian", "Cyclist")


def sides(root: Path) -> dict[str, np.ndarray]:
    """Per class, rows of (largest side gap to the camera projection px, the same to the LiDAR
    projection px, width over the LiDAR projection's width, bottom minus the camera projection's
    bottom px) of every untruncated label."""
    rows: dict[str, list] = {c: [] for c in CLASSES}
    for o, pc, pl in tqdm(box_projections(KittiDataset(root), CLASSES), desc=f"{root}", leave=False):
        bb = np.asarray(o.bbox)
        rows[o.type].append((np.abs(bb - pc).max(), np.abs(bb - pl).max(),
                             (bb[2] - bb[0]) / (pl[2] - pl[0]), bb[3] - pc[3]))
    return {c: np.array(r, dtype=float).reshape(-1, 4) for c, r in rows.items()}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, action="append", required=True, help="a KITTI root (repeat)")
    args = ap.parse_args(argv)
    print("| data | class | untruncated labels | largest side gap (px), median: camera / lidar projection "
          "| width / lidar projection's: median (p10, p90) | bottom above the camera projection's |")
    print("|---|---|---|---|---|---|")
    for root in args.data:
        for c, r in sides(root).items():
            if not len(r):
                continue
            q10, q50, q90 = np.percentile(r[:, 2], [10, 50, 90])
            print(f"| {root} | {c} | {len(r)} | {np.median(r[:, 0]):.2f} / {np.median(r[:, 1]):.2f} | "
                  f"{q50:.3f} ({q10:.3f}, {q90:.3f}) | {np.mean(r[:, 3] < -0.1):.2f} |")


if __name__ == "__main__":
    main()
