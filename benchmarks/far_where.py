"""Where the far returns lie, in two KITTI roots side by side: the heights and bearings of the
returns beyond a range (a diagnosis of the fidelity report's "share of returns beyond 40 m":
is the excess one kind of surface, or the same view open more often?).

    .venv/bin/python benchmarks/far_where.py --sim data/fidelity/urban200_win \\
        --real ../shared/kitti_real_dev [--range 40]

Far: the range from the sensor beyond `--range`, and the bearings' sectors, as the fidelity
report's rows (`testbed.fidelity.lidar`: FAR_M, SECTOR_DEG), which give their medians per frame;
this adds the pooled heights. Height: above a level road 1.73 m under the sensor (KITTI's
mounting height), measured along the rectified camera's vertical, which is level in KITTI's frames
and in generated ones; the LiDAR itself is tilted 0.6 deg forward and 0.6 deg left of it
(`simgen.rigs.kitti_lidar_tilt`), so its own z would read the far road 0.4 m high at 40 m ahead.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tqdm import tqdm

from kitti.dataset import KittiDataset
from simgen.rigs import KITTI_LIDAR_HEIGHT
from testbed.fidelity.lidar import FAR_M, SECTOR_DEG

BANDS = ((-np.inf, 0.5), (0.5, 3.0), (3.0, np.inf))  # m above the road (the top beam, +2 deg, is
# 4.5 m up at 80 m)


def far_returns(root: Path, far: float) -> tuple[np.ndarray, np.ndarray]:
    """Every frame's heights of its returns beyond `far` (pooled) and (frames, 4) shares of its
    returns beyond `far` ahead, beside, behind, and in all."""
    heights, shares = [], []
    ds = KittiDataset(root)
    for fid in tqdm(ds.ids(), desc=root.name, leave=False):
        p, calib = ds.velodyne(fid)[:, :3].astype(np.float64), ds.calib(fid)
        beyond = np.sqrt(np.einsum("ij,ij->i", p, p)) > far
        bearing = np.degrees(np.abs(np.arctan2(p[:, 1], p[:, 0])))
        down = calib.lidar_to_rect(np.vstack([np.zeros((1, 3)), p[beyond]]))[:, 1]  # rect y points down
        heights.append(down[0] + KITTI_LIDAR_HEIGHT - down[1:])
        ahead, behind = bearing < SECTOR_DEG, bearing >= 180.0 - SECTOR_DEG
        sectors = [ahead, ~ahead & ~behind, behind]
        shares.append([(beyond & s).sum() / len(p) for s in sectors] + [beyond.mean()])
    return np.concatenate(heights), np.array(shares)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--range", type=float, default=FAR_M[0], dest="far")
    args = ap.parse_args()
    print(f"| returns beyond {args.far:g} m | real | sim |\n|---|---|---|")
    rows: dict[str, list[str]] = {}
    for root in (args.real, args.sim):
        h, s = far_returns(root, args.far)
        med = np.median(s, axis=0)
        q = np.percentile(h, [10, 50, 90])
        rows.setdefault("frames", []).append(str(len(s)))
        rows.setdefault("share of a frame's returns (median)", []).append(f"{100 * med[3]:.2f} %")
        rows.setdefault("ahead / beside / behind (median shares)", []).append(
            " / ".join(f"{100 * m:.2f} %" for m in med[:3]))
        rows.setdefault("height above the road, quantiles 10 / 50 / 90 (m)", []).append(
            " / ".join(f"{v:.2f}" for v in q))
        rows.setdefault("below 0.5 / 0.5-3 / above 3 m (pooled)", []).append(
            " / ".join(f"{100 * np.mean((h >= lo) & (h < hi)):.0f} %" for lo, hi in BANDS))
    for name, (real, sim) in rows.items():
        print(f"| {name} | {real} | {sim} |")


if __name__ == "__main__":
    main()
