"""What a generated scan's far returns hit: the share of all returns that lie beyond a range, by
the material of the surface each came from (a diagnosis of the fidelity report's "share of
returns beyond 40 m").

    .venv/bin/python benchmarks/far_returns.py [--spec scenes/urban.yaml] [--frames 12] [--range 40]

Each return's ray is cast again from the sensor's origin at the return's firing time through the
point into the same Embree scene the scan used, and the triangle it hits names the material
(the lasers' few-centimetre offsets from that origin are ignored).
"""

from __future__ import annotations

import argparse
import collections

import numpy as np

from simgen import lidar
from simgen.lidar.target import build_target
from simgen.sample import sample_world
from simgen.spec import load_spec


def materials_hit(world, spec: lidar.LidarSpec, scan: lidar.LidarScan, tgt=None) -> np.ndarray:
    """Material name of the surface behind each return, 'none' where no triangle; 'window' where
    the ray meets a façade that can hold windows and the return lies more than 10 cm beyond it (a
    curtain or a room behind the glass: simgen.lidar.windows). `tgt`: the scan's own
    build_target(world, spec), if at hand."""
    tgt = tgt if tgt is not None else build_target(world, spec)
    poses = world.lidar_pose_at(scan.time.astype(np.float64))  # the sensor at each firing
    origin = poses[:, :3, 3]
    d = np.einsum("nij,nj->ni", poses[:, :3, :3], scan.points[:, :3].astype(np.float64))
    r = np.linalg.norm(d, axis=1)
    d /= r[:, None]
    res = tgt.scene.run(origin.astype(np.float32), d.astype(np.float32), output=1)
    prim = res["primID"]
    names = np.array([m.name for m in tgt.materials] + ["none", "window"])
    index = np.where(prim >= 0, tgt.tri_mat[np.maximum(prim, 0)], len(tgt.materials))
    behind = (prim >= 0) & (tgt.windows.tri_wall[np.maximum(prim, 0)] >= 0) & (r > res["tfar"] + 0.1)
    index[behind] = len(tgt.materials) + 1
    return names[index]


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
        swept = lidar.scan(world, sensor, 0)
        pts = swept.points[:, :3].astype(np.float64)
        names = materials_hit(world, sensor, swept)
        beyond = np.linalg.norm(pts, axis=1) > args.far
        n += len(pts)
        every.update(names.tolist())
        far.update(names[beyond].tolist())
    total = sum(far.values())
    print(f"{args.spec}, {args.frames} frames (seed {args.seed}): {100 * total / n:.2f} % of the "
          f"returns lie beyond {args.far:g} m")
    print(f"| material | share of all returns beyond {args.far:g} m (%) | share of the material's "
          f"returns that lie beyond (%) | share of all returns (%) |\n|---|---|---|---|")
    for name, k in far.most_common():
        print(f"| {name} | {100 * k / n:.2f} | {100 * k / every[name]:.1f} | {100 * every[name] / n:.2f} |")


if __name__ == "__main__":
    main()
