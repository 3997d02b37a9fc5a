"""Speed of `testbed fidelity`'s statistics pass: frames per second on a generated root and on real
KITTI, and what 1,000 frames against 1,000 would take on this machine.

    .venv/bin/python benchmarks/bench_fidelity.py --sim data/fidelity/urban200 \
        --real ../shared/kitti_real_dev --workers 2

Each root is read twice and the second pass is timed (the first warms numba and the file cache).
"""

from __future__ import annotations

import argparse
import time

from testbed.backends import LocalBackend
from testbed.fidelity import compute_stats


def rate(root: str, frames: int | None, backend: LocalBackend) -> tuple[int, float]:
    compute_stats(root, frames=frames, backend=backend)
    t0 = time.perf_counter()
    stats = compute_stats(root, frames=frames, backend=backend)
    return len(stats.frames), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", required=True)
    ap.add_argument("--real", required=True)
    ap.add_argument("--frames", type=int, default=None, help="first N frames of each root")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    with LocalBackend(args.workers) as backend:
        per_frame = {}
        for name, root in (("sim", args.sim), ("real", args.real)):
            n, dt = rate(root, args.frames, backend)
            per_frame[name] = dt / n
            print(f"{name}: {n} frames in {dt:.2f} s, {n / dt:.1f} frames/s ({args.workers} workers)")
    total = 1000 * (per_frame["sim"] + per_frame["real"])
    print(f"1,000 sim frames against 1,000 real frames: about {total:.0f} s")


if __name__ == "__main__":
    main()
