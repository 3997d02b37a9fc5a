"""Returns on far Cars against their distance, in KITTI roots side by side (a diagnosis of the
fidelity report's "points on a Car at 40-80 m": a median over one wide bin, which the mix of
distances inside the bin moves as much as the sensor does).

    .venv/bin/python benchmarks/far_car_points.py ../shared/kitti_real_dev data/s52/urban200

Per root: the Cars whose ground (x-z) distance from camera 0 lies in 40-80 m, their distance
quartiles, and per 10-20 m bin the median count of returns inside the label box
(`testbed.fidelity.lidar.returns_in_box`, as the report counts them), for all such Cars and the
fully visible ones (occlusion 0), with the share that have none.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from testbed.fidelity.lidar import returns_in_box

BINS = ((40, 50), (50, 60), (60, 80))


def far_cars(root: Path) -> np.ndarray:
    """(N, 3): distance, occlusion level and returns in the box of every Car at 40-80 m."""
    ds = KittiDataset(root)
    rows = []
    for fid in tqdm(ds.ids(None), desc=root.name):
        scan = ds.velodyne(fid)
        cars = [o for o in ds.labels(fid) if o.type == "Car"] if scan is not None else []
        if not cars:
            continue
        rect = ds.calib(fid).lidar_to_rect(scan[:, :3].astype(np.float64))
        x, z = np.ascontiguousarray(rect[:, 0]), np.ascontiguousarray(rect[:, 2])
        for o in cars:
            d = float(np.hypot(o.location[0], o.location[2]))
            if BINS[0][0] <= d < BINS[-1][1]:
                rows.append((d, o.occluded, len(returns_in_box(rect, x, z, o.box7))))
    return np.array(rows).reshape(-1, 3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", type=Path, nargs="+", help="KITTI-format roots with velodyne/")
    args = parser.parse_args()
    print("| root | bin (m) | Cars: all / fully visible | median returns: all / fully visible | "
          "share with none: all / fully visible |")
    print("|---|---|---|---|---|")
    for root in args.roots:
        a = far_cars(root)
        if not len(a):
            print(f"| {root} | 40-80 | 0 / 0 | | |")
            continue
        q = np.percentile(a[:, 0], [25, 50, 75])
        print(f"| {root} | 40-80 (distance quartiles {q[0]:.1f} / {q[1]:.1f} / {q[2]:.1f}) | "
              f"{len(a)} / {np.count_nonzero(a[:, 1] == 0)} | {np.median(a[:, 2]):.0f} | |")
        for lo, hi in BINS:
            b = a[(a[:, 0] >= lo) & (a[:, 0] < hi)]
            v = b[b[:, 1] == 0]
            med = " / ".join(f"{np.median(s[:, 2]):.0f}" if len(s) else "-" for s in (b, v))
            none = " / ".join(f"{np.mean(s[:, 2] == 0):.2f}" if len(s) else "-" for s in (b, v))
            print(f"| {root} | {lo}-{hi} | {len(b)} / {len(v)} | {med} | {none} |")


if __name__ == "__main__":
    main()
