"""How far the scan's road (`lifter.road.LocalRoad`, what `fit` stands a box on) lies from each
labelled Car's bottom, by side and distance: on a crowned street the half left of the ego lane
falls away, and a sparse scan leaves far cars without road returns near them. Moderate-like Cars
(occlusion <= 1, truncation <= 0.3, 2D height >= 25 px); the error is the label's bottom centre
above the local plane (m), and "frame's plane" the share of cars for which no window held road.

    .venv/bin/python benchmarks/road_under_cars.py --data data/lifter/tune4000c_d16 [--frames 80]
"""

from __future__ import annotations

import argparse

import numpy as np

from kitti.dataset import KittiDataset
from kitti.eval.protocol import outside_difficulty
from lifter.ground import fit_ground_plane, height_above
from lifter.points import frame_points
from lifter.road import LocalRoad

MODERATE = 1  # kitti.eval.protocol's difficulty index
SIDES = (("left of x = -6 m", -np.inf, -6.0), ("-6 to 2 m", -6.0, 2.0), ("right of x = 2 m", 2.0, np.inf))
RANGES = ((0.0, 20.0), (20.0, 35.0), (35.0, 60.0))


def errors(ds: KittiDataset, ids: list[str]) -> np.ndarray:
    """(x, distance, label bottom above the local road, 1 if the frame's plane) per moderate Car."""
    rows = []
    for fid in ids:
        pts = frame_points(ds.velodyne(fid), ds.calib(fid), None)  # as `fit` builds its road
        road = LocalRoad(pts.rect, fit_ground_plane(pts.rect), pts.sensor[[0, 2]])
        for o in ds.labels(fid):
            if o.type != "Car" or outside_difficulty(o.bbox[3] - o.bbox[1], o.occluded,
                                                   o.truncated, MODERATE):
                continue
            x, y, z = o.box7[:3]
            plane = road.plane_at(x, z)
            rows.append((x, np.hypot(x, z), height_above(np.array([[x, y, z]]), plane)[0],
                         float(np.allclose(plane, road.plane))))
    return np.array(rows).reshape(-1, 4)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default=None)
    ap.add_argument("--frames", type=int, default=None)
    args = ap.parse_args()
    ds = KittiDataset(args.data)
    e = errors(ds, ds.ids(args.split)[: args.frames])
    print(f"{args.data}: {len(e)} moderate Cars")
    print("| side (camera x) | distance (m) | cars | median (m) | RMS (m) | on the frame's plane |")
    print("|---|---|---|---|---|---|")
    for name, lo, hi in SIDES:
        for r0, r1 in RANGES:
            m = (e[:, 0] >= lo) & (e[:, 0] < hi) & (e[:, 1] >= r0) & (e[:, 1] < r1)
            if m.sum():
                print(f"| {name} | {r0:.0f}-{r1:.0f} | {m.sum()} | {np.median(e[m, 2]):+.3f} | "
                      f"{np.sqrt(np.mean(e[m, 2] ** 2)):.3f} | {e[m, 3].mean():.0%} |")


if __name__ == "__main__":
    main()
