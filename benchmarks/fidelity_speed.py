"""Speed of `testbed fidelity`: the statistics pass (frames per second on a generated root and on
real KITTI) and the bootstrap behind the verdicts' intervals, and what 1,000 frames against 1,000
would take on the machine it runs on (the bootstrap timed on each root's frames repeated to 1,000).

    .venv/bin/python benchmarks/fidelity_speed.py --sim SIM \
        --real ../shared/kitti_real_dev --workers 2

Each root is read twice and the second pass is timed (the first warms numba and the file cache).
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import time

import numpy as np

from testbed.backends import LocalBackend
from fidelity import DatasetStats, compare, compute_stats
from fidelity.bootstrap import DRAWS


def rate(root: str, frames: int | None, backend: LocalBackend) -> tuple[DatasetStats, float]:
    compute_stats(root, frames=frames, backend=backend)
    t0 = time.perf_counter()
    stats = compute_stats(root, frames=frames, backend=backend)
    return stats, time.perf_counter() - t0


def bootstrap_seconds(sim: DatasetStats, real: DatasetStats) -> float:
    t0 = time.perf_counter()
    compare(sim, real, draws=DRAWS)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", required=True)
    ap.add_argument("--real", required=True)
    ap.add_argument("--frames", type=int, default=None, help="first N frames of each root")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    with LocalBackend(args.workers) as backend:
        per_frame, stats = {}, {}
        for name, root in (("sim", args.sim), ("real", args.real)):
            stats[name], dt = rate(root, args.frames, backend)
            n = len(stats[name].frames)
            per_frame[name] = dt / n
            print(f"{name}: {n} frames in {dt:.2f} s, {n / dt:.1f} frames/s ({args.workers} workers)")
    boot = bootstrap_seconds(stats["sim"], stats["real"])
    print(f"bootstrap, {DRAWS} draws, {len(stats['sim'].frames)} against {len(stats['real'].frames)} "
          f"frames: {boot:.1f} s")
    big = {k: d.resample(np.resize(np.arange(len(d.frames)), 1000)) for k, d in stats.items()}
    boot_big = bootstrap_seconds(big["sim"], big["real"])
    print(f"bootstrap, {DRAWS} draws, 1,000 against 1,000 frames (each root's repeated): {boot_big:.1f} s")
    total = 1000 * (per_frame["sim"] + per_frame["real"]) + boot_big
    print(f"1,000 sim frames against 1,000 real frames: about {total:.0f} s")


if __name__ == "__main__":
    main()
