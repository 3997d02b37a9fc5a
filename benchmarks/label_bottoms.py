"""Where a Car label's box stands, by distance: KITTI's labels against the lowest return a
generated car gives its own sensor. The fidelity report's `lidar.car_bottom_above_road_m` fails
(generated boxes stand on the road, KITTI's a few centimetres above the road its scan shows);
this asks whether KITTI's annotators, who drew the boxes in the point clouds, put the bottom at
the lowest return on the car, which rises with distance as the rings spread.

    .venv/bin/python benchmarks/label_bottoms.py --real ../shared/kitti_real_dev \\
        --sim data/s52/urban200 [--frames 200]

Per distance bin: the generated labelled Cars' lowest own return (velodyne_info's actor ids, at
least 5 returns) above the road the lifter fits to the scan under the car
(`lifter.road.scan_road`), the generated labels' bottoms above it, and the real Car labels'
bottoms above theirs (each real value listed: they are few).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from kitti.velodyne_info import info_path, read_scan_info
from lifter.ground import height_above
from lifter.points import frame_points
from lifter.road import scan_road

BINS = ((0, 10), (10, 20), (20, 30), (30, 45), (45, 80))
MIN_RETURNS = 5


def _above(road, xyz) -> float:
    """Height of a rect-frame point above the scan's road plane at its x, z."""
    return float(height_above(np.asarray(xyz, dtype=np.float64)[None], road.plane_at(xyz[0], xyz[2]))[0])


def generated(root: Path, frames: int) -> np.ndarray:
    """(n, 3): ground distance, lowest own return above the road, label bottom above the road."""
    ds, rows = KittiDataset(root), []
    for fid in tqdm(ds.ids(None)[:frames], desc="generated"):
        v, calib = ds.velodyne(fid), ds.calib(fid)
        road = scan_road(frame_points(v, calib, None))
        actor = read_scan_info(info_path(root / "training", fid), len(v))["actor_id"]
        rect = calib.lidar_to_rect(v[:, :3].astype(np.float64))
        for a in json.loads((root / "training" / "meta" / f"{fid}.json").read_text())["actors"]:
            if a["class"] != "Car" or a.get("label") != "label":
                continue
            own = rect[actor == a["id"]]
            if len(own) < MIN_RETURNS:
                continue
            bottom = np.array(a["box7"][:3], dtype=np.float64)
            h = height_above(np.vstack([bottom, own]), road.plane_at(bottom[0], bottom[2]))
            rows.append((np.hypot(bottom[0], bottom[2]), float(h[1:].min()), float(h[0])))
    return np.array(rows).reshape(-1, 3)


def real(root: Path) -> np.ndarray:
    """(n, 2): ground distance and label bottom above the scan's road, every Car label."""
    ds, rows = KittiDataset(root), []
    for fid in ds.ids(None):
        road = scan_road(frame_points(ds.velodyne(fid), ds.calib(fid), None))
        rows += [(np.hypot(o.location[0], o.location[2]), _above(road, o.location))
                 for o in ds.labels(fid) if o.type == "Car"]
    return np.array(rows).reshape(-1, 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, required=True, help="a real KITTI root")
    parser.add_argument("--sim", type=Path, required=True, help="a generated root with velodyne_info")
    parser.add_argument("--frames", type=int, default=200)
    args = parser.parse_args()
    for path in (args.real, args.sim):
        if not (path / "training").is_dir():
            raise SystemExit(f"{path}: not a KITTI root (no training/)")
    g, r = generated(args.sim, args.frames), real(args.real)
    print(f"{len(g)} generated labelled Cars (>= {MIN_RETURNS} own returns) in {args.sim}, "
          f"{len(r)} Car labels in {args.real}; heights above the scan's road (m)\n")
    print("| distance (m) | generated: lowest own return, median (Cars) | generated: label bottom, "
          "median | real: label bottom, median (Cars) | real: each |")
    print("|---|---|---|---|---|")
    for lo, hi in BINS:
        gi, ri = g[(g[:, 0] >= lo) & (g[:, 0] < hi)], r[(r[:, 0] >= lo) & (r[:, 0] < hi)]
        med = (lambda a, k: f"{np.median(a[:, k]):+.3f}" if len(a) else "-")
        print(f"| {lo}-{hi} | {med(gi, 1)} ({len(gi)}) | {med(gi, 2)} | {med(ri, 1)} ({len(ri)}) | "
              + " ".join(f"{v:+.2f}" for v in ri[:, 1]) + " |")


if __name__ == "__main__":
    main()
