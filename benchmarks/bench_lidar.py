"""LiDAR sweep cost against its limit, the bare Embree query of the same rays, on one core.

For 16, 32, 64 (hdl64e) and 128 beams on sampled scenes/urban.yaml worlds: the best-of-N wall
time of (a) one bare `EmbreeScene.run(origins, dirs, output=1)` of the sweep's rays and (b) one
full `scan` (the rays that pass glass and leaves cast again, ego and actor motion, echo
strength, detection threshold, per-laser drop-out, noise and bias, the reflectance channel with
per-laser gains and zero shares, scatter, floors and quantisation); the Embree scene build is
timed apart (it is shared by both and by every sensor of a sweep over beams). Then the
KITTI-likeness of default hdl64e sweeps: points, range profile, reflectance, and the same under
fog and rain.
Usage: .venv/bin/python benchmarks/bench_lidar.py [--frames N] [--timing-frames N] [--repeats R]
    [--spec scenes/urban.yaml]
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from simgen.lidar import CLUTTER_ID, build_target, preset, ray_table, scan  # noqa: E402
from simgen.lidar.windows import windows_of  # noqa: E402
from simgen.sample import sample_world  # noqa: E402
from simgen.spec import load_spec  # noqa: E402
from simgen.world import Weather  # noqa: E402


def best_ms(fns, repeats: int) -> list[float]:
    """Best wall time and best CPU time of this thread for each function, run alternately so
    that all see the same machine load; thread CPU time leaves out time lost to other
    processes on a shared machine."""
    wall = [np.inf] * len(fns)
    cpu = [np.inf] * len(fns)
    for _ in range(repeats + 1):
        for k, fn in enumerate(fns):
            c, t = time.thread_time(), time.perf_counter()
            fn()
            wall[k] = min(wall[k], time.perf_counter() - t)
            cpu[k] = min(cpu[k], time.thread_time() - c)
    return [b * 1e3 for b in wall + cpu]


def ms(fn) -> float:
    t = time.perf_counter()
    fn()
    return (time.perf_counter() - t) * 1e3


def rotated(a: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """(N, 3) float32 rows turned by the 3 x 3 `rot`, elementwise as `simgen.lidar.scan` turns
    the ray table into the world frame."""
    m = np.asarray(rot, dtype=np.float32)
    return np.ascontiguousarray(a[:, 0:1] * m[:, 0] + a[:, 1:2] * m[:, 1] + a[:, 2:3] * m[:, 2])


def bare_query(world, spec, tgt):
    """One Embree query of exactly the sweep's rays (the public `ray_table`, turned with the
    rig), built before the clock starts."""
    rays = ray_table(spec)
    rot = world.lidar_pose[:3, :3]
    d = rotated(rays.dirs32, rot)
    o = np.empty_like(d)
    np.multiply(rays.time32[:, None], np.asarray(world.ego_velocity, np.float32)[None], out=o)
    o += world.lidar_pose[:3, 3].astype(np.float32)
    if rays.source is not None:  # the same rays as the sweep's: each from its laser's source
        o += rotated(rays.source, rot)
    return lambda: tgt.scene.run(o, d, dists=spec.max_range + 1.0, output=1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=10, help="urban worlds for the statistics")
    ap.add_argument("--timing-frames", type=int, default=3, help="urban worlds for the timings")
    ap.add_argument("--repeats", type=int, default=25)
    ap.add_argument("--spec", default="scenes/urban.yaml", help="the worlds' scene spec")
    args = ap.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core
    spec_u = load_spec(args.spec)
    sensors = {16: preset("uniform", beams=16), 32: preset("uniform", beams=32),
               64: preset("hdl64e"), 128: preset("uniform", beams=128)}

    rows = {b: [] for b in sensors}
    builds, windows = [], []
    for i in tqdm(range(args.timing_frames), desc="timing"):
        world = sample_world(spec_u, spec_u.seed, i)
        for beams, spec in sensors.items():
            t = time.perf_counter()
            tgt = build_target(world, spec)
            builds.append((time.perf_counter() - t) * 1e3)
            if beams == 64:
                windows.append(min(ms(lambda: windows_of(world, tgt.n_triangles)) for _ in range(5)))
            bare, full, bare_cpu, full_cpu = best_ms(
                [bare_query(world, spec, tgt), lambda: scan(world, spec, 0, target=tgt)],
                args.repeats)
            rows[beams].append((bare, full, len(ray_table(spec).time), tgt.n_triangles,
                                bare_cpu, full_cpu))

    print(f"one core, best of {args.repeats}, mean over {args.timing_frames} urban worlds")
    print(f"{'':>13} {'wall time, ms':^27} {'thread CPU time, ms':^27}")
    print(f"{'beams':>5} {'rays':>7} {'bare':>8} {'sweep':>8} {'ratio':>7}   {'bare':>8} "
          f"{'sweep':>8} {'ratio':>7}")
    for beams, r in rows.items():
        a = np.asarray(r)
        print(f"{beams:>5} {int(a[0, 2]):>7} {a[:, 0].mean():>8.1f} {a[:, 1].mean():>8.1f} "
              f"{(a[:, 1] / a[:, 0]).mean():>7.2f}   {a[:, 4].mean():>8.1f} {a[:, 5].mean():>8.1f} "
              f"{(a[:, 5] / a[:, 4]).mean():>7.2f}")
    print(f"Embree scene build (triangles {int(np.mean([r[3] for r in rows[64]]))}): "
          f"{np.mean(builds):.1f} ms mean, of which the façades' window table "
          f"(simgen.lidar.windows) {np.mean(windows):.1f} ms (best of 5)")

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

    print("hdl64e on urban world 0, seed 0, under weather:")
    world = sample_world(spec_u, spec_u.seed, 0)
    for wx in (Weather(), Weather(rain_rate=2.0), Weather(rain_rate=10.0),
               Weather(rain_rate=50.0), Weather(fog_extinction=0.01),
               Weather(fog_extinction=0.03), Weather(fog_extinction=0.1)):
        s = scan(dataclasses.replace(world, weather=wx), spec, 0)
        r = np.linalg.norm(s.points[:, :3], axis=1)
        c = s.actor_id == CLUTTER_ID
        print(f"  fog {wx.fog_extinction:<5} rain {wx.rain_rate:<5} points {len(s):7d}  clutter "
              f"{c.mean():7.2%} (median {np.median(r[c]) if c.any() else 0:4.1f} m)  farthest "
              f"{r.max():6.1f} m  beyond 40 m {(r > 40).mean():6.2%}")


if __name__ == "__main__":
    main()
