"""Sweep throughput: frames re-scanned, lifted and evaluated per second, with 1 and 2 workers.

The base dataset is generated once (not timed); each timed run re-scans it with four LiDAR
configurations and lifts (fit, frustum) and evaluates every point, on the local process pool.

    .venv/bin/python benchmarks/bench_sweep.py [--frames 12]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from testbed import stages
from testbed.backends import LocalBackend
from testbed.golden import GOLDEN_DIR
from testbed.sweep import Axes, SceneRef, SweepSpec, execute, plan, scene_name


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=12)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        spec = SweepSpec(name="bench", scenes=[SceneRef(spec=GOLDEN_DIR / "street.yaml", frames=args.frames)],
                         axes=Axes(beams=[64, 32, 16, 8], method=["fit", "frustum"], boxes=["gt"]),
                         split="val", data_dir=Path(tmp))
        p = plan(spec)
        generator, models = p.versions
        scene = scene_name(spec.scenes[0])
        base = p.base_dir(scene, generator)  # where `execute` finds the frames done
        with LocalBackend(2) as backend:
            stages.generate(spec.scenes[0].spec, base, args.frames, None, backend)
        n_val = len((base / "ImageSets" / "val.txt").read_text().split())
        print(f"{args.frames} frames ({n_val} in val), {len(p.scans)} scans x {n_val} frames, "
              f"{len(p.points)} lift+evaluate points")
        base_rate = None
        for workers in (1, 2):
            shutil.rmtree(p.scan_dir(scene, generator, p.scans[0]).parent, ignore_errors=True)
            shutil.rmtree(p.points_dir(f"{generator}-{models}"), ignore_errors=True)
            t = time.perf_counter()
            with LocalBackend(workers) as backend:
                execute(p, backend)
            dt = time.perf_counter() - t
            frames = len(p.points) * n_val
            rate = frames / dt
            base_rate = base_rate or rate
            print(f"workers={workers}: {dt:6.1f} s, {frames / dt:5.2f} point-frames/s "
                  f"({len(p.scans) * args.frames / dt:5.2f} frames re-scanned/s incl. lifting), "
                  f"speed-up {rate / base_rate:4.2f}x")


if __name__ == "__main__":
    main()
