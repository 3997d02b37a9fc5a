"""How the returns on near Cars read, in two KITTI roots side by side: the share that reads 0
against the incidence of the beam on the car's surface and against the face of the car it lies on,
and the nonzero readings' median (a diagnosis of the fidelity report's "share of the points on a
Car at 0-20 m that read 0").

    .venv/bin/python benchmarks/car_readings.py --sim ROOT \\
        --real ../shared/kitti_real_dev [--near 20] [--frames 60] [--map cars.png]

Points on a Car: the returns inside its label box (`kitti.boxes.points_in_boxes`), Cars nearer
than `--near` (ground distance). Incidence: |cos| between the beam (sensor to point) and the
surface normal, the normal being the direction of least spread of the point's 12 nearest
neighbours on the same Car (so a car with fewer than 30 points is left out). Face: the box axis
that normal lies closest to: along the car's length a front or rear face (bumpers, lamps, plates,
tailgate), across it a side (doors, wings), upright the top (roof, bonnet, boot lid). `--map`
draws each side's six Cars with the most returns in the car's own frame, from the side and from
an end, the returns that read 0 in red.
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from dataclasses import dataclass
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
FACES = ("side", "front or rear", "top")
BOTTOM_M = 0.05  # a return this close to its box's bottom face is likely the road under the box
MAP_CARS = 6


def surface(points: np.ndarray, origin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|cos| of each point's beam (from `origin`) against its local surface normal, and that
    normal (N, 3)."""
    _, nb = cKDTree(points).query(points, k=NEIGHBOURS)
    local = points[nb] - points[nb].mean(axis=1, keepdims=True)  # (N, k, 3)
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
    normal = vecs[:, :, 0]  # eigenvector of the smallest eigenvalue
    beam = points - origin
    beam /= np.linalg.norm(beam, axis=1, keepdims=True)
    return np.abs(np.einsum("ij,ij->i", normal, beam)), normal


@dataclass
class CarReturns:
    """The returns on one root's near Cars: each return's reading, incidence and face (an index
    into FACES), per Car its share read 0 and nonzero median, and the Cars in their own frames."""

    refl: np.ndarray
    cos: np.ndarray
    face: np.ndarray
    per_car: np.ndarray             # (C, 2)
    views: list[tuple[str, float, np.ndarray, np.ndarray]]  # (frame, distance, (n, 3) u w h, refl)


def car_frame(rect: np.ndarray, location: np.ndarray, ry: float) -> tuple[np.ndarray, np.ndarray]:
    """The car's axes in rect coordinates (length, width, up; rows) and its points in them."""
    axes = np.array([[np.cos(ry), 0.0, -np.sin(ry)], [np.sin(ry), 0.0, np.cos(ry)], [0.0, -1.0, 0.0]])
    return axes, (rect - location) @ axes.T


def car_returns(root: Path, near: float, frames: int) -> CarReturns:
    t = root / "training"
    refl, cos, face, per_car, views = [], [], [], [], []
    for label in tqdm(sorted((t / "label_2").glob("*.txt"))[:frames], desc=root.name, leave=False):
        cars = [o for o in read_label(label) if o.type == "Car"
                and np.hypot(o.location[0], o.location[2]) < near]
        if not cars:
            continue
        scan = read_velodyne(t / "velodyne" / f"{label.stem}.bin")
        calib = read_calib(t / "calib" / f"{label.stem}.txt")
        rect = calib.lidar_to_rect(scan[:, :3].astype(np.float64))
        origin = calib.lidar_to_rect(np.zeros((1, 3)))[0]
        for o, inside in zip(cars, points_in_boxes(rect, np.stack([o.box7 for o in cars]))):
            if inside.sum() < MIN_POINTS:
                continue
            r = scan[inside, 3]
            c, normal = surface(rect[inside], origin)
            axes, own = car_frame(rect[inside], np.asarray(o.location, dtype=np.float64), o.rotation_y)
            face.append(np.argmax(np.abs(normal @ axes.T), axis=1).choose([1, 0, 2]))
            refl.append(r)
            cos.append(c)
            per_car.append((np.mean(r == 0), np.median(r[r > 0]) if (r > 0).any() else np.nan))
            views.append((label.stem, float(np.hypot(o.location[0], o.location[2])), own, r))
    return CarReturns(np.concatenate(refl), np.concatenate(cos), np.concatenate(face),
                      np.array(per_car), views)


def cell(v: np.ndarray) -> str:
    nz = v[v > 0]
    return f"{len(v):,}, {np.mean(v == 0):.2f}, {np.median(nz):.2f}" if len(nz) else f"{len(v):,}"


def draw_map(sides: dict[str, CarReturns], out: Path) -> None:
    """Each side's MAP_CARS Cars with the most returns: side view (length x height) and end view
    (width x height) in the car's frame, readings in colour, zeros in red."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(MAP_CARS, 4, figsize=(16, 2.3 * MAP_CARS), squeeze=False)
    for col, (name, cars) in enumerate(sides.items()):
        for row, (stem, dist, own, r) in enumerate(sorted(cars.views, key=lambda v: -len(v[3]))[:MAP_CARS]):
            zero = r == 0
            for k, horizontal in enumerate((0, 1)):  # along the length, then across
                ax = axes[row, 2 * col + k]
                ax.scatter(own[~zero, horizontal], own[~zero, 2], c=r[~zero], s=2, cmap="viridis",
                           vmin=0, vmax=0.6)
                ax.scatter(own[zero, horizontal], own[zero, 2], c="red", s=2)
                ax.set_aspect("equal")
                ax.tick_params(labelsize=6)
            axes[row, 2 * col].set_title(f"{name} {stem}, {dist:.1f} m: {len(r)} returns, "
                                         f"{zero.mean():.2f} read 0", fontsize=8)
    fig.suptitle("near Cars in their own frames: side view (length x up) and end view (width x up); "
                 "red: read 0", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=90)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--real", type=Path, required=True)
    ap.add_argument("--near", type=float, default=20.0)
    ap.add_argument("--frames", type=int, default=60, help="at most this many frames a root")
    ap.add_argument("--map", type=Path, help="PNG of the Cars with the most returns, zeros in red")
    args = ap.parse_args()
    sides = {name: car_returns(root, args.near, args.frames)
             for name, root in (("sim", args.sim), ("real", args.real))}
    print(f"Returns on Cars nearer than {args.near:.0f} m: " + ", ".join(
        f"{name} {len(c.refl):,}, {np.mean(c.refl == 0):.2f} read 0" for name, c in sides.items()))
    print("| incidence cos | sim: returns, share read 0, nonzero median | real: the same |")
    print("|---|---|---|")
    for lo, hi in zip(COS_BINS[:-1], COS_BINS[1:]):
        cells = [cell(c.refl[(c.cos >= lo) & (c.cos < hi)]) for c in sides.values()]
        print(f"| {lo:.2f}-{min(hi, 1.0):.2f} | {cells[0]} | {cells[1]} |")
    print("\n| face | sim: returns, share read 0, nonzero median | real: the same |")
    print("|---|---|---|")
    for k, face in enumerate(FACES):
        cells = [cell(c.refl[c.face == k]) for c in sides.values()]
        print(f"| {face} | {cells[0]} | {cells[1]} |")
    print(f"\nReturns within {BOTTOM_M * 100:.0f} cm of their box's bottom face (road returns where a box "
          "stands on the road), and the median Car's share read 0 without them:")
    for name, c in sides.items():
        low = [v[2][:, 2] < BOTTOM_M for v in c.views]
        kept = [np.mean(v[3][~m] == 0) for v, m in zip(c.views, low) if (~m).any()]
        print(f"- {name}: {np.mean(np.concatenate(low)):.3f} of the returns; {np.median(kept):.3f} "
              f"(with them {np.median(c.per_car[:, 0]):.3f})")
    print("\nPer Car (10th / 25th / 50th / 75th / 90th percentile over the Cars):")
    print("| side | Cars | share read 0 | nonzero median |")
    print("|---|---|---|---|")
    for name, c in sides.items():
        q = (lambda v: " / ".join(f"{x:.2f}" for x in np.nanpercentile(v, PERCENTILES)))
        print(f"| {name} | {len(c.per_car)} | {q(c.per_car[:, 0])} | {q(c.per_car[:, 1])} |")
    if args.map:
        draw_map(sides, args.map)
        print(f"\nwrote {args.map}")


if __name__ == "__main__":
    main()
