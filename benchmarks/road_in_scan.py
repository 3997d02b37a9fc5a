"""How the road lies in the scans of two KITTI roots side by side: the slope of the road plane
fitted to each scan, in the LiDAR's frame, and what the beams that should meet the road far ahead
return instead.

    .venv/bin/python benchmarks/road_in_scan.py --sim data/fidelity/urban200_tilt \\
        --real ../shared/kitti_real_dev [--frames 200]

Plane: `lifter.ground.fit_ground_plane` on the scan in the rectified camera frame (as the
fidelity report fits it), turned into the LiDAR frame with the frame's calibration; its rise
ahead and to the left (deg) and the sensor's height above it. KITTI's calibration tilts the
LiDAR 0.6 deg forward and 0.6 deg to the left of the level rectified camera
(`simgen.rigs.kitti_lidar_tilt`), so a level road rises ahead in its scans.

Beams ahead: for each ring (`kitti.rings.recover_rings`, median elevation e) whose flat-road
intercept d = 1.73 m / tan(-e) lies 25-80 m away, its firings within 20 deg of ahead (as many a
turn as the `simgen.lidar` preset `hdl64e` fires, KITTI's HDL-64E at 10 Hz) split by what they returned:
ground near the intercept (0.75-1.33 d, within 0.25 m of the fitted plane), ground nearer
(a road rising ahead, or a tilted sensor), something else nearer, or nothing at all.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from kitti.rings import recover_rings
from lifter.ground import fit_ground_plane, height_above
from simgen.lidar import preset
from simgen.rigs import KITTI_LIDAR_HEIGHT

FIRINGS_PER_DEG = preset("hdl64e").columns / 360.0
AHEAD_DEG = 20.0
BANDS = ((25, 35), (35, 45), (45, 55), (55, 80))
GROUND_M = 0.25


def scan_rows(root: Path, frames: int | None) -> tuple[np.ndarray, np.ndarray]:
    """Per frame (rise ahead deg, rise left deg, height m); per ring and frame (intercept m,
    shares of its firings ahead: ground at the intercept, ground nearer, other nearer, any)."""
    ds = KittiDataset(root)
    planes, rings = [], []
    for fid in tqdm(ds.ids()[:frames], desc=root.name, leave=False):
        v, calib = ds.velodyne(fid)[:, :3].astype(np.float64), ds.calib(fid)
        rect = calib.lidar_to_rect(v)
        plane = fit_ground_plane(rect)
        up = calib.velo_to_rect[:3, :3].T @ plane[:3]  # the plane's normal in the LiDAR frame,
        up *= np.sign(up[2]) / np.linalg.norm(up)  # pointing up
        origin = calib.lidar_to_rect(np.zeros((1, 3)))
        planes.append((np.degrees(np.arctan2(-up[0], up[2])), np.degrees(np.arctan2(-up[1], up[2])),
                       abs(float(height_above(origin, plane)[0])) / np.linalg.norm(plane[:3])))
        h = height_above(rect, plane)
        rings = recover_rings(v.astype(np.float32), 64)
        ring = rings.ring
        bev = np.hypot(v[:, 0], v[:, 1])
        ahead = np.abs(np.degrees(np.arctan2(v[:, 1], v[:, 0]))) < AHEAD_DEG
        ground = np.abs(h) < GROUND_M
        for k in range(64):
            on = ring == k
            if on.sum() < 100:
                continue
            e = float(np.degrees(rings.elevation[k]))
            if e >= 0.0:
                continue
            d = KITTI_LIDAR_HEIGHT / np.tan(np.radians(-e))
            if not BANDS[0][0] <= d < BANDS[-1][1]:
                continue
            sel = on & ahead
            near = sel & (bev < 0.75 * d)
            firings = 2 * AHEAD_DEG * FIRINGS_PER_DEG
            rings.append((d, (sel & ground & (bev >= 0.75 * d) & (bev < 1.33 * d)).sum() / firings,
                          (near & ground).sum() / firings, (near & ~ground).sum() / firings,
                          sel.sum() / firings))
    return np.array(planes), np.array(rings)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--frames", type=int, default=200, help="first frames of --sim (--real: all)")
    args = ap.parse_args()
    sides = {"generated": scan_rows(args.sim, args.frames), "real": scan_rows(args.real, None)}
    print("| fitted road plane, LiDAR frame (10th / 50th / 90th percentile) | generated | real |\n"
          "|---|---|---|")
    names = ("rise ahead (deg)", "rise to the left (deg)", "sensor height above it (m)")
    for j, name in enumerate(names):
        cells = [" / ".join(f"{x:.2f}" for x in np.percentile(p[:, j], [10, 50, 90]))
                 for p, _ in sides.values()]
        print(f"| {name} | {cells[0]} | {cells[1]} |")
    print("\nFirings within 20 deg of ahead of the rings whose flat-road intercept d lies in each band "
          "(mean share over ring-frames):\n")
    print("| intercept | side | ring-frames | ground at d | ground nearer | other nearer | nothing |\n"
          "|---|---|---:|---:|---:|---:|---:|")
    for lo, hi in BANDS:
        for side, (_, r) in sides.items():
            s = r[(r[:, 0] >= lo) & (r[:, 0] < hi)]
            if len(s):
                m = s[:, 1:].mean(axis=0)
                print(f"| {lo}-{hi} m | {side} | {len(s)} | {m[0]:.2f} | {m[1]:.2f} | {m[2]:.2f} | "
                      f"{max(0.0, 1.0 - m[3]):.2f} |")


if __name__ == "__main__":
    main()
