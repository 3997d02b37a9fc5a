"""What a generated scan's firings ahead that return nothing would have met: each such firing of
the rings whose flat-road intercept lies in a range band is cast again, from the sensor's origin,
into the scan's own Embree scene, and the first surface it meets is named by its material (a
diagnosis of `benchmarks/road_in_scan.py`'s "nothing" column, which KITTI's scans hardly show).

    .venv/bin/python benchmarks/missing_returns.py [--spec scenes/urban.yaml] [--frames 12]

A firing is missing when the scan holds no return of its ring at its azimuth; "hidden by the
car" are the directions the car under the sensor hides (`simgen.lidar.platform`). The lasers'
few-centimetre offsets from the origin are ignored.
"""

from __future__ import annotations

import argparse
import collections

import numpy as np
from tqdm import tqdm

from simgen import lidar
from simgen.lidar.platform import hidden_rays
from simgen.lidar.rays import ray_table
from simgen.lidar.target import build_target
from simgen.rigs import KITTI_LIDAR_HEIGHT
from simgen.sample import sample_world
from simgen.spec import load_spec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="scenes/urban.yaml")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--band", type=float, nargs=2, default=(40.0, 80.0), help="flat-road intercept, m")
    ap.add_argument("--ahead", type=float, default=20.0, help="half-width of the sector ahead, deg")
    args = ap.parse_args()
    spec = load_spec(args.spec)
    sensor = lidar.preset(spec.lidar.preset, beams=spec.lidar.beams, max_range=spec.lidar.max_range)
    rays, hidden = ray_table(sensor), hidden_rays(sensor)
    el = np.asarray(sensor.elevations_deg)
    with np.errstate(divide="ignore"):
        intercept = np.where(el < 0, KITTI_LIDAR_HEIGHT / np.tan(np.radians(-el)), np.inf)
    rings = np.flatnonzero((intercept >= args.band[0]) & (intercept < args.band[1]))
    fired = np.flatnonzero(np.isin(rays.ring, rings) & (np.abs(np.degrees(rays.azimuth)) < args.ahead))
    met, n = collections.Counter(), 0
    for i in tqdm(range(args.frames), desc="frames"):
        world = sample_world(spec, args.seed, i)
        target = build_target(world, sensor)
        swept = lidar.scan(world, sensor, 0, target)
        returned = set(zip(swept.ring.tolist(), swept.azimuth.tolist()))
        miss = np.array([j for j in fired
                         if (int(rays.ring[j]), float(rays.azimuth[j])) not in returned], int)
        n += len(fired)
        met["hidden by the car"] += int(hidden[miss].sum())
        miss = miss[~hidden[miss]]
        if not len(miss):
            continue
        pose = world.lidar_pose
        hit = target.scene.run(np.repeat(pose[None, :3, 3], len(miss), 0).astype(np.float32),
                               (rays.dirs[miss] @ pose[:3, :3].T).astype(np.float32), output=1)
        for prim, t in zip(hit["primID"], hit["tfar"]):
            name = target.materials[target.tri_mat[prim]].name if prim >= 0 else "nothing"
            met[f"{name}, {'within' if t <= sensor.max_range else 'beyond'} {sensor.max_range:g} m"] += 1
    print(f"{args.spec}, {args.frames} frames (seed {args.seed}): rings with their flat-road intercept at "
          f"{args.band[0]:g}-{args.band[1]:g} m ({len(rings)}), firings within {args.ahead:g} deg of ahead: "
          f"{n}, of which {sum(met.values())} ({100 * sum(met.values()) / n:.1f} %) return nothing")
    print("| first surface the firing meets | share of the firings (%) |\n|---|---:|")
    for name, k in met.most_common():
        if k:
            print(f"| {name} | {100 * k / n:.2f} |")


if __name__ == "__main__":
    main()
