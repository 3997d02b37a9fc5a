"""Lifter speed: milliseconds per frame of each lifting method, the LiDAR part alone and the whole
lift with the size/orientation network.

    .venv/bin/python benchmarks/bench_lifter.py [--data ROOT] [--split S] [--frames 50]
        [--methods fit,mono,frustum]

Without `--data` it first generates `--frames` frames of `--spec` (default `scenes/urban.yaml`)
with `--seed` (default 2000, the held-out seed) into a temporary folder, untimed, and times those.

Per frame, "lift" is what `lifter.pipeline.lift_frame` does: the LiDAR transform to the camera
frame, the road (fit: the frame's plane and the road returns near each object) and the lifting of
every labelled road user's box, with the size and orientation the network gave (`--priors net`,
computed beforehand; `truth`: the labels'). "network" is the network's forward pass over the
frame's crops (one batch, crops cut from the decoded image), "whole" both together; file reading
is timed apart. Wall time and the process's CPU time are both printed: on a shared,
oversubscribed machine the CPU time is the figure that means something. The per-frame figures are
steady-state: a first pass over the frames is timed apart, and what it costs above the steady
state is the one-off work (imports, numba's kernels compiled or, with their cache, loaded).
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from kitti.dataset import KittiDataset
from lifter.methods import METHODS
from lifter.pipeline import box_outline, lift_frame, oracle_boxes, truth_priors
from lifter.predictor import DEFAULT_WEIGHTS, Predictor


def timed(fn) -> tuple[object, float, float]:
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, 1000 * (time.perf_counter() - t), 1000 * (time.process_time() - c)


def load(ds: KittiDataset, ids: list[str], pred: Predictor, priors: str) -> tuple[list, list]:
    """Per frame the lift_frame arguments, the decoded image and the boxes; the read times."""
    frames, read_ms = [], []
    for fid in ids:
        (labels, img, calib, size, velo, planes), ms, _ = timed(lambda fid=fid: (
            ds.labels(fid), ds.image(fid), ds.calib(fid), ds.image_size(fid), ds.velodyne(fid),
            ds.planes(fid)))
        read_ms.append(ms)
        boxes = oracle_boxes(labels)
        pr = truth_priors(boxes, labels) if priors == "truth" else pred(img, boxes)
        frames.append(((boxes, pr, calib, size, velo, planes), img))
    return frames, read_ms


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", help="a KITTI root with velodyne/ (default: frames generated for the run)")
    ap.add_argument("--spec", default="scenes/urban.yaml", help="what to generate without --data")
    ap.add_argument("--seed", type=int, default=2000, help="the generated frames' seed without --data")
    ap.add_argument("--split", default=None)
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--priors", default="net", choices=["net", "truth"])
    ap.add_argument("--weights", default=str(DEFAULT_WEIGHTS))
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--methods", default=",".join(METHODS))
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    tmp = None
    if args.data is None:
        from simgen.generate import generate
        from simgen.spec import load_spec
        from testbed.backends import LocalBackend

        tmp = Path(tempfile.mkdtemp(prefix="bench_lifter_"))
        args.data = str(tmp / "data")
        print(f"generating {args.frames} frames of {args.spec} (seed {args.seed}) into {args.data}")
        with LocalBackend(workers=2) as backend:
            generate(load_spec(args.spec), args.data, frames=args.frames, seed=args.seed, backend=backend)
    try:
        run(args)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def run(args: argparse.Namespace) -> None:
    ds = KittiDataset(args.data)
    outline = box_outline(args.data, None)
    pred = Predictor(args.weights, threads=args.threads)
    frames, read_ms = load(ds, ds.ids(args.split)[: args.frames], pred, args.priors)
    n_boxes = sum(len(f[0][0]) for f in frames)
    print(f"{len(frames)} frames of {args.data}, {n_boxes} boxes ({n_boxes / len(frames):.1f}/frame), "
          f"{np.mean([len(f[0][4]) for f in frames]):.0f} returns/frame, priors: {args.priors}; "
          f"reading a frame's files {np.mean(read_ms):.1f} ms")
    net = [timed(lambda a=a, img=img: pred(img, a[0]))[1:] for a, img in frames]
    net_ms, net_cpu = np.mean(net, axis=0)
    print(f"{'network':9s} wall mean {net_ms:7.2f} ms/frame, CPU mean {net_cpu:7.2f} ms/frame "
          f"(crops {pred.size} px, one batch per frame, {args.threads} thread(s))")
    for method in args.methods.split(","):
        # warm-up: every frame once, as a kernel may first run on any of them
        _, first_ms, _ = timed(lambda m=method: [lift_frame(m, *a, outline) for a, _ in frames])
        t = np.array([timed(lambda a=a, m=method: lift_frame(m, *a, outline))[1:]
                      for a, _ in frames])
        ms, cms = t[:, 0], t[:, 1]
        print(f"{method:9s} lift wall mean {ms.mean():7.2f} ms/frame (median {np.median(ms):7.2f}), "
              f"CPU mean {cms.mean():7.2f} (median {np.median(cms):7.2f}), "
              f"{cms.sum() / max(n_boxes, 1):.2f} CPU ms/box; whole (network + lift) "
              f"{net_ms + ms.mean():7.2f} ms/frame wall, {net_cpu + cms.mean():7.2f} CPU; "
              f"first pass {first_ms - ms.sum():.0f} ms wall above the steady state "
              f"(imports, numba compile or cache load)")


if __name__ == "__main__":
    main()
