"""How many returns on far Cars the LiDAR's power threshold removes, by the paint's 905 nm
reflectance (a diagnosis of the fidelity report's `lidar.car_points_40_80m`, 8 returns against
the dev frames' 20, and of `benchmarks/far_car_points.py`'s per-bin gap).

    .venv/bin/python benchmarks/far_car_dropouts.py [--spec scenes/urban.yaml] [--frames 60] [--seed S]

Each world of the spec (frames 0..N-1 of the seed, by default the spec's) is scanned twice with
the spec's LiDAR and the frame's own LiDAR seed: as `testbed generate` scans it, and with
`LidarSpec.detection` off (every hit within range kept: what the beams' geometry, glass and leaves
allow). Per distance bin, the
labelled fully visible Cars (occlusion 0, the generator's own labels): their median returns both
ways and the share of the geometric returns the threshold keeps; at 40-80 m the same per band of
the body paint's 905 nm reflectance (`simgen.materials.nir_reflectivity` of its colour).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from tqdm import tqdm

from simgen import lidar
from simgen.labels import derive
from simgen.lidar.target import build_target
from simgen.materials import nir_reflectivity
from simgen.render import render
from simgen.rescan import lidar_seed
from simgen.sample import sample_world
from simgen.spec import load_spec

BINS = ((0, 20), (20, 40), (40, 80))
PAINT_BANDS = ((0.0, 0.15, "black"), (0.15, 0.30, "dark grey, green"),
               (0.30, 0.60, "silver, blue, red, beige"), (0.60, 1.0, "white"))


def cars(spec, seed: int, frames: int) -> np.ndarray:
    """(N, 4): distance, returns as scanned, returns without the threshold, paint reflectance."""
    section = spec.lidar
    if section is None:
        raise SystemExit(f"{spec.name}: the spec has no LiDAR")
    sensor = lidar.preset(section.preset, beams=section.beams, max_range=section.max_range)
    geometric = dataclasses.replace(sensor, detection=False)
    rows = []
    for i in tqdm(range(frames), desc="worlds", unit="frame"):
        world = sample_world(spec, seed, i)
        target = build_target(world, sensor)
        kept = lidar.scan(world, sensor, lidar_seed(seed, i), target).point_counts()
        every = lidar.scan(world, geometric, lidar_seed(seed, i), target).point_counts()
        _, truths = derive(world, render(world).instance, spec.labels, kept)
        paint = {a.id: nir_reflectivity(a.recipe["color"]) for a in world.actors if "color" in a.recipe}
        rows += [(t.distance, kept.get(t.id, 0), every.get(t.id, 0), paint.get(t.id, np.nan))
                 for t in truths if t.cls == "Car" and t.label == "label" and t.occluded == 0]
    return np.array(rows, float).reshape(-1, 4)


def _row(label: str, rows: np.ndarray) -> str:
    if not len(rows):
        return f"| {label} | 0 | | | |"
    kept = rows[:, 1].sum() / max(rows[:, 2].sum(), 1.0)
    return (f"| {label} | {len(rows)} | {np.median(rows[:, 1]):.0f} | {np.median(rows[:, 2]):.0f} | "
            f"{kept:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", default="scenes/urban.yaml")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--seed", type=int, help="the worlds' seed (default: the spec's)")
    args = ap.parse_args()
    spec = load_spec(args.spec)
    seed = spec.seed if args.seed is None else args.seed
    rows = cars(spec, seed, args.frames)
    print(f"{spec.name}, frames 0-{args.frames - 1} (seed {seed}): fully visible labelled Cars")
    print("| Cars | n | median returns, as scanned | median returns, no power threshold | "
          "returns kept (sum / sum) |")
    print("|---|---:|---:|---:|---:|")
    for lo, hi in BINS:
        print(_row(f"{lo}-{hi} m", rows[(rows[:, 0] >= lo) & (rows[:, 0] < hi)]))
    far = rows[(rows[:, 0] >= 40) & (rows[:, 0] < 80)]
    for lo, hi, name in PAINT_BANDS:
        print(_row(f"40-80 m, paint {lo:.2f}-{hi:.2f} at 905 nm ({name})",
                   far[(far[:, 3] >= lo) & (far[:, 3] < hi)]))


if __name__ == "__main__":
    main()
