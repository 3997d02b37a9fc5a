"""How low a car's rear face reaches, read from the LiDAR returns on the cars straight ahead,
in KITTI roots side by side (made for the real dev frames against generated ones): below a car's
rear bumper the beams pass on to the road under it and to the rear tyres, so the lowest return on
the rear face is the height of the rear overhang's underside, which simgen.meshes.DEPARTURE_DEG
sets for generated cars.

A car straight ahead: a Car label within 2 m of the camera's axis (|x| < 2), 5-12 m ahead (z),
occlusion at most 1, heading within 20 deg of the camera's. Its rear face: the returns within
0.25 m of the box's near end, across the middle of its width (0.25 m in from each side, clear of
the wheels' outer faces), between 0.05 m above the box bottom (clear of the road) and 1 m. Heights
are above the box bottom, which stands on the road. At 8 m the HDL-64E's rings lie about 5 cm apart
there, so a band of 15 cm without returns is seen by three rings or more.

    .venv/bin/python benchmarks/car_rear.py --root ../shared/kitti_real_dev \\
        --root data/fidelity/urban200_rear [--root ...]
"""

from __future__ import annotations

import argparse

import numpy as np

from kitti.boxes import points_in_boxes
from kitti.dataset import KittiDataset
from lifter.points import frame_points

AXIS_M, NEAR_M, FAR_M = 2.0, 5.0, 12.0
FACE_M, SIDE_M, ROAD_M, TOP_M = 0.25, 0.25, 0.05, 1.0
HEADING_DEG = 20.0


def rear_face_lows(ds: KittiDataset) -> np.ndarray:
    """(distance, lowest rear-face return above the box bottom) of each car straight ahead."""
    rows = []
    for fid in ds.ids():
        cloud = ds.velodyne(fid)
        if cloud is None:
            continue
        rect = None
        for o in ds.labels(fid):
            x, y, z, _, w, length, ry = o.box7
            off_axis = np.degrees(np.arccos(min(1.0, abs(np.sin(ry)))))  # its length from the z axis
            if (o.type != "Car" or o.occluded > 1 or abs(x) >= AXIS_M or not NEAR_M < z < FAR_M
                    or off_axis > HEADING_DEG):
                continue
            if rect is None:
                rect = frame_points(cloud, ds.calib(fid), None).rect
            axis = np.array([np.cos(ry), 0.0, -np.sin(ry)])  # the box's length direction
            end = np.array([x, y, z]) - np.sign(axis @ [x, y, z]) * length / 2 * axis  # facing the camera
            slab = [*(end - [0.0, ROAD_M, 0.0]), TOP_M - ROAD_M, w - 2 * SIDE_M, 2 * FACE_M, ry]
            face = points_in_boxes(rect, slab)[0]  # the rear face's slab, ROAD_M to TOP_M up
            if face.any():
                rows.append((np.hypot(x, z), float(y - rect[face, 1].max())))
    return np.array(rows).reshape(-1, 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", action="append", required=True, help="a KITTI root (repeatable)")
    args = ap.parse_args()
    print("| root | cars straight ahead, 5-12 m | lowest rear-face return above the road (m): median | "
          "10th-90th percentile |")
    print("|---|---:|---:|---|")
    for root in args.root:
        r = rear_face_lows(KittiDataset(root))
        if not len(r):
            print(f"| `{root}` | 0 | | |")
            continue
        p10, p50, p90 = np.percentile(r[:, 1], [10, 50, 90])
        print(f"| `{root}` | {len(r)} | {p50:.2f} | {p10:.2f}-{p90:.2f} |")


if __name__ == "__main__":
    main()
