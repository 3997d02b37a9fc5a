"""What a generated scan's far returns hit: the share of all returns that lie beyond a range, by
the material of the surface each came from (a diagnosis of the fidelity report's "share of
returns beyond 40 m").

    .venv/bin/python benchmarks/far_returns.py [--spec scenes/urban.yaml] [--frames 12] [--range 40]

Each return's ray is cast again from the sensor's origin of the sweep's start through the point
(the ego's motion during the sweep is ignored: a few centimetres at these speeds) into the same
Embree scene the scan used, and the triangle it hits names the material.
"""

from __future__ import annotations

import argparse
import collections

import numpy as np

from simgen import lidar
from simgen.lidar.target import build_target
from simgen.sample import sample_world
from simgen.spec import load_spec


def materials_hit(world, spec: lidar.LidarSpec, points: np.ndarray) -> np.ndarray:
    """Material name of the surface behind each point (sensor frame), 'none' where no triangle."""
    tgt = build_target(world, spec)
    rot, origin = world.lidar_pose[:3, :3], world.lidar_pose[:3, 3]
    d = points @ rot.T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    prim = tgt.scene.run(np.repeat(origin[None].astype(np.float32), len(d), 0), d.astype(np.float32))
    names = np.array([m.name for m in tgt.materials] + ["none"])
    return names[np.where(prim >= 0, tgt.tri_mat[np.maximum(prim, 0)], len(tgt.materials))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="scenes/urban.yaml")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--range", type=float, default=40.0, dest="far")
    args = ap.parse_args()
    spec = load_spec(args.spec)
    sensor = lidar.preset(spec.lidar.preset, beams=spec.lidar.beams, max_range=spec.lidar.max_range)
    far, every, n = collections.Counter(), collections.Counter(), 0
    for i in range(args.frames):
        world = sample_world(spec, args.seed, i)
        pts = lidar.scan(world, sensor, 0).points[:, :3].astype(np.float64)
        names = materials_hit(world, sensor, pts)
        beyond = np.linalg.norm(pts, axis=1) > args.far
        n += len(pts)
        every.update(names.tolist())
        far.update(names[beyond].tolist())
    total = sum(far.values())
    print(f"{args.spec}, {args.frames} frames (seed {args.seed}): {100 * total / n:.2f} % of the "
          f"returns lie beyond {args.far:g} m")
    print(f"| material | share of all returns beyond {args.far:g} m (%) | share of the material's "
          "returns that lie beyond (%) |\n|---|---|---|")
    for name, k in far.most_common():
        print(f"| {name} | {100 * k / n:.2f} | {100 * k / every[name]:.1f} |")


if __name__ == "__main__":
    main()
