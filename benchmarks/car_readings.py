"""How the returns on near Cars read, in two KITTI roots side by side: the share that reads 0
against the incidence of the beam on the car's surface, and the nonzero readings' median (a
diagnosis of the fidelity report's "share of the points on a Car at 0-20 m that read 0").

    .venv/bin/python benchmarks/car_readings.py --sim data/fidelity/urban200_reading \\
        --real ../shared/kitti_real_dev [--near 20] [--frames 60]

Points on a Car: the returns inside its label box (`kitti.boxes.points_in_boxes`), Cars nearer
than `--near` (ground distance). Incidence: |cos| between the beam (sensor to point) and the
surface normal, the normal being the direction of least spread of the point's 12 nearest
neighbours on the same Car (so a car with fewer than 30 points is left out).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from tqdm import tqdm

from kitti.boxes import points_in_boxes
from kitti.calib import read_calib
from kitti.labels import read_label
from kitti.velodyne import read_velodyne

NEIGHBOURS = 12
MIN_POINTS = 30
COS_BINS = (0.0, 0.3, 0.5, 0.7, 0.85, 0.95, 1.0001)
PERCENTILES = (10, 25, 50, 75, 90)


def incidence(points: np.ndarray) -> np.ndarray:
    """|cos| of each point's beam (from the origin) against its local surface normal."""
    _, nb = cKDTree(points).query(points, k=NEIGHBOURS)
    local = points[nb] - points[nb].mean(axis=1, keepdims=True)  # (N, k, 3)
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    normal = vecs[:, :, 0]  # eigenvector of the smallest eigenvalue
    beam = points / np.linalg.norm(points, axis=1, keepdims=True)
    return np.abs(np.einsum("ij,ij->i", normal, beam))


def car_returns(root: Path, near: float, frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reflectance and incidence of every return on a Car nearer than `near` m, and per Car its
    share of returns that read 0 and its nonzero median (NaN when none is nonzero): (C, 2)."""
    t = root / "training"
    refl, cos, per_car = [], [], []
    for label in tqdm(sorted((t / "label_2").glob("*.txt"))[:frames], desc=root.name, leave=False):
        cars = [o for o in read_label(label) if o.type == "Car"
                and np.hypot(o.location[0], o.location[2]) < near]
        if not cars:
            continue
        scan = read_velodyne(t / "velodyne" / f"{label.stem}.bin")
        rect = read_calib(t / "calib" / f"{label.stem}.txt").lidar_to_rect(scan[:, :3].astype(np.float64))
        for inside in points_in_boxes(rect, np.stack([o.box7 for o in cars])):
            if inside.sum() >= MIN_POINTS:
                r = scan[inside, 3]
                refl.append(r)
                cos.append(incidence(scan[inside, :3].astype(np.float64)))
                per_car.append((np.mean(r == 0), np.median(r[r > 0]) if (r > 0).any() else np.nan))
    return np.concatenate(refl), np.concatenate(cos), np.array(per_car)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--near", type=float, default=20.0)
    ap.add_argument("--frames", type=int, default=60, help="at most this many frames a root")
    args = ap.parse_args()
    sides = {name: car_returns(root, args.near, args.frames)
             for name, root in (("sim", args.sim), ("real", args.real))}
    print(f"Returns on Cars nearer than {args.near:.0f} m: " + ", ".join(
        f"{name} {len(r):,}, {np.mean(r == 0):.2f} read 0" for name, (r, _, _) in sides.items()))
    print("| incidence cos | sim: returns, share read 0, nonzero median | real: the same |")
    print("|---|---|---|")
    for lo, hi in zip(COS_BINS[:-1], COS_BINS[1:]):
        cells = []
        for r, c, _ in sides.values():
            v = r[(c >= lo) & (c < hi)]
            nz = v[v > 0]
            cells.append(f"{len(v):,}, {np.mean(v == 0):.2f}, {np.median(nz):.2f}" if len(nz) else f"{len(v):,}")
        print(f"| {lo:.2f}-{min(hi, 1.0):.2f} | {cells[0]} | {cells[1]} |")
    print("\nPer Car (10th / 25th / 50th / 75th / 90th percentile over the Cars):")
    print("| side | Cars | share read 0 | nonzero median |")
    print("|---|---|---|---|")
    for name, (_, _, cars) in sides.items():
        q = (lambda v: " / ".join(f"{x:.2f}" for x in np.nanpercentile(v, PERCENTILES)))
        print(f"| {name} | {len(cars)} | {q(cars[:, 0])} | {q(cars[:, 1])} |")


if __name__ == "__main__":
    main()
