"""Evaluation speed on a random set the size of KITTI val (the budget: under 10 s on a
2-core CPU, first call included).

3,769 frames, about 8 truth objects (Car/Van/Pedestrian/Person_sitting/Cyclist/DontCare, all
difficulties) and 15 detections each (noisy copies of most truth boxes plus false positives), all
classes and metrics (2D, BEV, 3D, AOS; R11 and R40; strict and loose). The first call includes
numba's compile time when its cache is cold (run with NUMBA_CACHE_DIR pointing at an empty folder
to measure that case); the second call is the steady state. Then once more with range bins, and
with `--bootstrap N` the 95 % intervals of `testbed evaluate --bootstrap` over N draws of the frames
(`kitti.eval.bootstrap`: every AP of every draw).

    .venv/bin/python benchmarks/bench_eval.py [--frames 3769] [--files] [--bootstrap 20]
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from kitti.labels import Object3D, write_label

TYPES = np.array(["Car", "Car", "Car", "Car", "Van", "Pedestrian", "Pedestrian", "Person_sitting",
                  "Cyclist", "DontCare"])
SIZE = {"Car": (1.5, 1.6, 3.9), "Van": (2.2, 1.9, 5.0), "Pedestrian": (1.75, 0.6, 0.8),
        "Person_sitting": (1.2, 0.6, 0.8), "Cyclist": (1.7, 0.6, 1.8)}
F_PX, CU, CV = 721.5377, 609.5593, 172.854


def bbox_of(x, y, z, h, w, l):
    """A simple projection of the box (pinhole, no rotation): enough for plausible 2D boxes."""
    half = 0.5 * max(w, l)
    u1, u2 = F_PX * (x - half) / z + CU, F_PX * (x + half) / z + CU
    v1, v2 = F_PX * (y - h) / z + CV, F_PX * y / z + CV
    return np.clip([u1, v1, u2, v2], [0, 0, 0, 0], [1241, 374, 1241, 374])


def frame(rng: np.random.Generator, n_gt: int, n_dt: int) -> tuple[list[Object3D], list[Object3D]]:
    gt = []
    for _ in range(n_gt):
        t = str(rng.choice(TYPES))
        z, x = rng.uniform(4, 70), rng.uniform(-15, 15)
        if t == "DontCare":
            u, v = rng.uniform(0, 1100), rng.uniform(100, 300)
            gt.append(Object3D.dont_care([u, v, u + rng.uniform(10, 100), v + rng.uniform(10, 60)]))
            continue
        h, w, l = (s * rng.uniform(0.9, 1.1) for s in SIZE[t])
        ry = rng.uniform(-np.pi, np.pi)
        gt.append(Object3D(t, float(rng.choice([0.0, 0.1, 0.3, 0.6])), int(rng.integers(0, 4)),
                           float(ry - np.arctan2(x, z)), bbox_of(x, 1.65, z, h, w, l), h, w, l,
                           [x, 1.65, z], ry))
    real = [o for o in gt if o.type != "DontCare"]
    dt = []
    for o in real[:n_dt]:
        if rng.random() < 0.85:
            loc = o.location + rng.normal(0, [0.1, 0.03, 0.2])
            h, w, l = (v * rng.uniform(0.95, 1.05) for v in (o.h, o.w, o.l))
            ry = o.rotation_y + rng.normal(0, 0.1)
            t = "Car" if o.type == "Van" and rng.random() < 0.5 else o.type
            dt.append(Object3D(t, 0.0, 0, float(ry - np.arctan2(loc[0], loc[2])),
                               o.bbox + rng.normal(0, 1.5, 4), h, w, l, loc, ry, float(rng.uniform(0.3, 1))))
    while len(dt) < n_dt:
        t = str(rng.choice(["Car", "Pedestrian", "Cyclist"]))
        z, x = rng.uniform(4, 70), rng.uniform(-15, 15)
        h, w, l = SIZE[t]
        ry = rng.uniform(-np.pi, np.pi)
        dt.append(Object3D(t, 0.0, 0, float(ry - np.arctan2(x, z)), bbox_of(x, 1.65, z, h, w, l), h, w, l,
                           [x, 1.65, z], ry, float(rng.uniform(0, 0.8))))
    return gt, dt


def dataset(seed: int = 0, frames: int = 3769) -> tuple[dict, dict]:
    rng = np.random.default_rng(seed)
    gt, dt = {}, {}
    for i in range(frames):
        fid = f"{i:06d}"
        gt[fid], dt[fid] = frame(rng, int(rng.poisson(8)), int(rng.poisson(15)))
    return gt, dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=3769)
    ap.add_argument("--files", action="store_true",
                    help="also write the set to data/bench_eval/ and time `testbed evaluate` on it")
    ap.add_argument("--bootstrap", type=int, default=0, metavar="DRAWS",
                    help="also time the bootstrap intervals over this many draws")
    args = ap.parse_args()
    gt, dt = dataset(0, args.frames)
    n_gt = sum(len(v) for v in gt.values())
    n_dt = sum(len(v) for v in dt.values())
    print(f"{args.frames} frames, {n_gt} truth objects ({n_gt / args.frames:.1f}/frame), "
          f"{n_dt} detections ({n_dt / args.frames:.1f}/frame)")
    t = time.perf_counter()
    from kitti.eval import evaluate  # import (numba included) counts as part of the first call
    res = evaluate(gt, dt)
    t1 = time.perf_counter() - t
    print(f"first call (import + compile or cache load + evaluate): {t1:6.2f} s")
    t = time.perf_counter()
    res = evaluate(gt, dt)
    print(f"second call (all classes, 2d/bev/3d/aos, R11+R40, strict+loose): "
          f"{time.perf_counter() - t:6.2f} s")
    t = time.perf_counter()
    evaluate(gt, dt, range_bins=[0, 20, 40, 60, 80])
    print(f"with --range-bins 0,20,40,60,80: {time.perf_counter() - t:6.2f} s")
    if args.bootstrap:
        from kitti.eval.bootstrap import bootstrap_ap

        t = time.perf_counter()
        bootstrap_ap(gt, {"pred": dt}, ("Car", "Pedestrian", "Cyclist"), ("2d", "bev", "3d", "aos"),
                     draws=args.bootstrap)
        took = time.perf_counter() - t
        print(f"bootstrap, {args.bootstrap} draws (all classes, 2d/bev/3d/aos, strict+loose): "
              f"{took:6.2f} s, {took / args.bootstrap:5.2f} s a draw")
    if args.files:
        root = Path(tempfile.mkdtemp(prefix="bench_eval_"))
        for sub, frames in (("label_2", gt), ("results", dt)):
            for fid, objs in frames.items():
                write_label(root / sub / f"{fid}.txt", objs)
        t = time.perf_counter()
        testbed = str(Path(sys.executable).parent / "testbed")
        subprocess.run([testbed, "evaluate", "--gt", str(root / "label_2"), "--pred", str(root / "results"),
                        "--json", str(root / "eval.json")],
                       check=True, stdout=subprocess.DEVNULL)
        print(f"`testbed evaluate` on the files (new process, reading 2 x {args.frames} files): "
              f"{time.perf_counter() - t:6.2f} s")
        shutil.rmtree(root, ignore_errors=True)
    print()
    print(res.table())


if __name__ == "__main__":
    main()
