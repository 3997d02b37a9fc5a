"""LiDAR sweep cost against its limit, the bare Embree query of the same rays, on one core.

For 16, 32, 64 (hdl64e) and 128 beams on sampled scenes/urban.yaml worlds: the best-of-N wall
time of (a) one bare `EmbreeScene.run(origins, dirs, output=1)` of the sweep's rays and (b) one
full `scan` (ego motion, actor motion, noise, per-laser bias, intensity, detection threshold,
drop-out); the Embree scene build is timed apart (it is shared by both and by every sensor of
a sweep over beams). Then the KITTI-likeness of default hdl64e sweeps: points, range profile,
reflectance. Usage: .venv/bin/python benchmarks/bench_lidar.py [--frames N] [--repeats R]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from simgen.lidar import build_target, preset, ray_table, scan  # noqa: E402
from simgen.lidar.scan import _world_dirs  # noqa: E402
from simgen.sample import sample_world  # noqa: E402
from simgen.spec import load_spec  # noqa: E402


def best_ms(fns, repeats: int) -> list[float]:
    """Best wall time of each function, run alternately so that both see the same machine load."""
    best = [np.inf] * len(fns)
    for _ in range(repeats + 1):
        for k, fn in enumerate(fns):
            t = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t)
    return [b * 1e3 for b in best]


def bare_query(world, spec, tgt):
    rays = ray_table(spec)
    d = _world_dirs(spec, tuple(world.lidar_pose[:3, :3].ravel().tolist()))
    o = np.empty_like(d)
    np.multiply(rays.time32[:, None], np.asarray(world.ego_velocity, np.float32)[None], out=o)
    o += world.lidar_pose[:3, 3].astype(np.float32)
    return lambda: tgt.scene.run(o, d, dists=spec.max_range + 1.0, output=1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=10, help="urban worlds for the statistics")
    ap.add_argument("--timing-frames", type=int, default=3, help="urban worlds for the timings")
    ap.add_argument("--repeats", type=int, default=25)
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core
    spec_u = load_spec("scenes/urban.yaml")
    sensors = {16: preset("uniform", beams=16), 32: preset("uniform", beams=32),
               64: preset("hdl64e"), 128: preset("uniform", beams=128)}

    rows = {b: [] for b in sensors}
    builds = []
    for i in tqdm(range(args.timing_frames), desc="timing"):
        world = sample_world(spec_u, spec_u.seed, i)
        for beams, spec in sensors.items():
            t = time.perf_counter()
            tgt = build_target(world, spec)
            builds.append((time.perf_counter() - t) * 1e3)
            bare, full = best_ms([bare_query(world, spec, tgt),
                                  lambda: scan(world, spec, 0, target=tgt)], args.repeats)
            rows[beams].append((bare, full, len(ray_table(spec).time), tgt.n_triangles))

    print(f"one core, best of {args.repeats}, mean over {args.timing_frames} urban worlds")
    print(f"{'beams':>5} {'rays':>7} {'bare query ms':>14} {'full sweep ms':>14} {'ratio':>6} "
          f"{'physics ms':>10}")
    for beams, r in rows.items():
        a = np.asarray(r)
        print(f"{beams:>5} {int(a[0, 2]):>7} {a[:, 0].mean():>14.1f} {a[:, 1].mean():>14.1f} "
              f"{(a[:, 1] / a[:, 0]).mean():>6.2f} {(a[:, 1] - a[:, 0]).mean():>10.1f}")
    print(f"Embree scene build (triangles {int(np.mean([r[3] for r in rows[64]]))}): "
          f"{np.mean(builds):.1f} ms mean")

    spec = preset("hdl64e")
    stats = []
    for i in tqdm(range(args.frames), desc="hdl64e urban sweeps"):
        world = sample_world(spec_u, spec_u.seed, i)
        s = scan(world, spec, i)
        r = np.linalg.norm(s.points[:, :3], axis=1)
        ring_counts = np.bincount(s.ring, minlength=64)
        stats.append((len(s), np.median(r), (r > 40).mean(), (r > 80).mean(), r.max(),
                      s.points[:, 3].mean(), (s.points[:, 3] == 0).mean(),
                      np.median(ring_counts)))
    a = np.asarray(stats)
    print(f"hdl64e on {args.frames} urban worlds (mean, [min, max]):")
    names = ["points", "median range m", "share > 40 m", "share > 80 m", "max range m",
             "mean reflectance", "share reflectance 0", "median returns per ring"]
    for k, name in enumerate(names):
        print(f"  {name:>24}: {a[:, k].mean():10.4g}  [{a[:, k].min():.4g}, {a[:, k].max():.4g}]")


if __name__ == "__main__":
    main()
