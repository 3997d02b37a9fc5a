"""How many LiDAR returns each label stands on, generated against real (a diagnosis for issue 14's
label gap).

KITTI's objects were annotated as 3D boxes in the Velodyne point clouds (Geiger et al., IJRR 2013),
so an object the scan barely touches is hard to label there; the devkit's only word on the
rule is that DontCare marks regions "too far away from the laser scanner". This script counts,
for every labelled Car, Pedestrian and Cyclist (DontCare left out), the returns of the frame's
.bin inside its 3D box, and prints per class and ground-distance bin the labels and the share of
them on 0 and on fewer than 5, 10 and 20 returns; then the median ground distance and 2D box
height of all labels and of those on at least 1, 5, 10 and 20 returns (what a rule asking that
many returns would leave), and the share of them under 25 px, which no KITTI difficulty
evaluates. The counts 1, 5, 10, 20 are reporting steps, not fitted thresholds.

    .venv/bin/python benchmarks/label_support.py --data data/fidelity/urban200_edges \
        --data ../shared/kitti_real_dev
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from kitti.eval.protocol import MIN_HEIGHT
from testbed.fidelity.lidar import returns_in_box

CLASSES = ("Car", "Pedestrian", "Cyclist")
DIST_EDGES = (0.0, 20.0, 40.0, 60.0, 80.0, np.inf)  # m, ground (x-z) distance of the label
STEPS = (1, 5, 10, 20)  # returns
MIN_HEIGHT_PX = MIN_HEIGHT[1]  # the devkit's moderate and hard minimum: a lower label is never evaluated


def support(root: Path) -> dict[str, np.ndarray]:
    """Per class, rows of (returns inside the box, ground distance, 2D box height) of every label."""
    ds = KittiDataset(root)
    rows: dict[str, list] = {c: [] for c in CLASSES}
    for fid in tqdm(ds.ids(), desc=f"{root}", leave=False):
        objs = [o for o in ds.labels(fid) if o.type in CLASSES]
        scan = ds.velodyne(fid)
        if not objs or scan is None:
            continue
        rect = ds.calib(fid).lidar_to_rect(scan[:, :3].astype(np.float64))
        x, z = np.ascontiguousarray(rect[:, 0]), np.ascontiguousarray(rect[:, 2])
        for o in objs:
            b = o.box7
            n = len(returns_in_box(rect, x, z, b))
            rows[o.type].append((n, float(np.hypot(b[0], b[2])), float(o.bbox[3] - o.bbox[1])))
    return {c: np.array(r, dtype=float).reshape(-1, 3) for c, r in rows.items()}


def report(name: str, sup: dict[str, np.ndarray]) -> None:
    print(f"\n### {name}\n")
    print("| class | distance (m) | labels | on 0 returns | < 5 | < 10 | < 20 |")
    print("|---|---|---|---|---|---|---|")
    for c in CLASSES:
        r = sup[c]
        for lo, hi in zip(DIST_EDGES, DIST_EDGES[1:]):
            m = (r[:, 1] >= lo) & (r[:, 1] < hi)
            if not m.any():
                continue
            n = r[m, 0]
            span = f"{lo:g}-{hi:g}" if np.isfinite(hi) else f">= {lo:g}"
            print(f"| {c} | {span} | {m.sum()} | " + " | ".join(
                f"{100 * np.mean(n < k):.0f} %" for k in (1, 5, 10, 20)) + " |")
    print("\n| class | labels kept | all | on >= " + " | on >= ".join(str(k) for k in STEPS) + " |")
    print("|---|---|---" + "|---" * len(STEPS) + "|")
    for c in CLASSES:
        r = sup[c]
        if not len(r):
            continue
        keep = [np.ones(len(r), bool)] + [r[:, 0] >= k for k in STEPS]
        print(f"| {c} | count | " + " | ".join(str(int(k.sum())) for k in keep) + " |")
        for col, what in ((1, "median distance (m)"), (2, "median 2D height (px)")):
            print(f"| {c} | {what} | " + " | ".join(
                f"{np.median(r[k, col]):.1f}" if k.any() else "-" for k in keep) + " |")
        print(f"| {c} | share under {MIN_HEIGHT_PX} px | " + " | ".join(
            f"{100 * np.mean(r[k, 2] < MIN_HEIGHT_PX):.0f} %" if k.any() else "-" for k in keep) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, action="append", type=Path, help="KITTI root with velodyne/")
    args = ap.parse_args()
    for root in args.data:
        report(str(root), support(root))


if __name__ == "__main__":
    main()
