"""Lifter speed: milliseconds per frame of each lifting method without the network (size and
orientation from the labels), and of the network per crop.

    .venv/bin/python benchmarks/bench_lifter.py --data data/urban_val_hdl64 --split val --frames 50

Per frame: the LiDAR transform to the camera frame, the road plane (fit) and the lifting of every
labelled road user's box; file reading is not counted. Wall time and the process's CPU time are
both printed: on a shared, oversubscribed machine the CPU time is the figure that means something.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from kitti.dataset import KittiDataset
from lifter.methods import METHODS
from lifter.pipeline import lift_frame, oracle_boxes, truth_priors
from lifter.predictor import DEFAULT_WEIGHTS, Predictor


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default=None)
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--weights", default=str(DEFAULT_WEIGHTS))
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    ds = KittiDataset(args.data)
    ids = ds.ids(args.split)[: args.frames]
    frames = []
    for fid in ids:
        labels = ds.labels(fid)
        boxes = oracle_boxes(labels)
        frames.append((boxes, truth_priors(boxes, labels), ds.calib(fid), ds.image_size(fid),
                       ds.velodyne(fid), ds.planes(fid), fid))
    n_boxes = sum(len(f[0]) for f in frames)
    print(f"{len(frames)} frames of {args.data}, {n_boxes} boxes ({n_boxes / len(frames):.1f}/frame), "
          f"{np.mean([len(f[4]) for f in frames]):.0f} returns/frame")
    for method in METHODS:
        lift_frame(method, *frames[0][:6])  # warm-up
        times, cpu = [], []
        for f in frames:
            t, c = time.perf_counter(), time.process_time()
            lift_frame(method, *f[:6])
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        ms, cms = 1000 * np.array(times), 1000 * np.array(cpu)
        print(f"{method:9s} wall mean {ms.mean():7.2f} ms/frame (median {np.median(ms):7.2f}), "
              f"CPU mean {cms.mean():7.2f} ms/frame (median {np.median(cms):7.2f}), "
              f"{cms.sum() / max(n_boxes, 1):.2f} CPU ms/box")
    pred = Predictor(args.weights)
    img = ds.image(frames[0][6])
    boxes = [b for f in frames for b in f[0]][:64] or []
    if boxes:
        pred(img, boxes[:1])
        t = time.perf_counter()
        for b in boxes:
            pred(img, [b])
        one = 1000 * (time.perf_counter() - t) / len(boxes)
        t = time.perf_counter()
        pred(img, boxes)
        batched = 1000 * (time.perf_counter() - t) / len(boxes)
        print(f"network   {one:.2f} ms/crop one at a time, {batched:.2f} ms/crop batched "
              f"({len(boxes)} crops, crop {pred.size} px, {args.threads} thread(s))")


if __name__ == "__main__":
    main()
