"""The camera's tone: which exposure key and output curve give generated frames the pixel
statistics of KITTI's whole training set.

Detection code that normalises KITTI inputs publishes the per-channel mean and standard deviation
of every pixel of the training images: mean 93.8 / 98.8 / 95.9, SD 78.8 / 80.1 / 81.2 (RGB). This
script renders the frames of a spec once, then puts them through `simgen.camera.expose` with each
key and output gamma and prints the pooled mean and SD of the 8-bit pixels, as those figures were
computed (every pixel of every frame). With `--balance` it instead finds the gains on the raw
channels (`simgen.camera.BALANCE`) that give the frames the set's three channel means at the
default key and curve: from neutral gains, each step multiplies a channel's gain by (the set's
mean / the frames' mean) ** gamma, then divides all three by the least (a camera's digital gains
are at least 1; the exposure meters the balanced image, so the level is the key's). Nothing here
reads a real frame.

    .venv/bin/python benchmarks/tone_curve.py [--spec scenes/urban.yaml] [--frames 24] [--balance]
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import dataclasses

import cv2
import numpy as np
from tqdm import tqdm

from simgen import camera
from simgen.factors import factor_rng
from simgen.look import rendered_radiance
from simgen.render import render
from simgen.sample import sample_world
from simgen.spec import load_spec
from fidelity.images import KITTI_TRAINING_PIXEL_MEAN, KITTI_TRAINING_PIXEL_SD

KITTI_MEAN = np.array(KITTI_TRAINING_PIXEL_MEAN)
KITTI_SD = np.array(KITTI_TRAINING_PIXEL_SD)


def pooled(images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per-channel mean and SD over every pixel of every image."""
    s = np.zeros(3)
    s2 = np.zeros(3)
    n = 0
    for im in images:
        px = im.reshape(-1, 3).astype(np.float64)
        s += px.sum(axis=0)
        s2 += np.square(px).sum(axis=0)
        n += len(px)
    mean = s / n
    return mean, np.sqrt(s2 / n - mean * mean)


def saturation(images: list[np.ndarray]) -> float:
    """Median over frames of the mean HSV saturation (as `testbed fidelity` reports it)."""
    return float(np.median([cv2.cvtColor(im, cv2.COLOR_RGB2HSV)[..., 1].mean() for im in images]))


def find_balance(frames: list, seed: int, steps: int = 8) -> np.ndarray:
    """The raw channels' gains whose frames have KITTI's channel means (fixed-point steps)."""
    gains = np.ones(3)
    print(f"KITTI training set: mean R / G / B {' / '.join(f'{v:.1f}' for v in KITTI_MEAN)}")
    print("| step | gains R / G / B | mean R / G / B | saturation |")
    print("|---|---|---|---|")
    for step in range(steps + 1):
        imgs = [camera.expose(lin, K, cam, factor_rng(seed, i, "look"), balance=tuple(gains))
                for lin, K, cam, i in frames]
        m, _ = pooled(imgs)
        print(f"| {step} | {' / '.join(f'{g:.4f}' for g in gains)} | "
              f"{' / '.join(f'{v:.1f}' for v in m)} | {saturation(imgs):.1f} |")
        gains = gains * (KITTI_MEAN / m) ** frames[0][2].gamma
        gains = gains / gains.min()  # a camera's digital gains: none below 1, so white clips white
    return gains


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="scenes/urban.yaml")
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--keys", type=float, nargs="+", default=[0.05, 0.07, 0.10, 0.14, 0.18])
    ap.add_argument("--gammas", type=float, nargs="+", default=[1.0, 1.4, 1.8, 2.2])
    ap.add_argument("--balance", action="store_true",
                    help="find the channel gains that give the set's channel means")
    args = ap.parse_args()
    spec = load_spec(args.spec)
    frames = []
    for i in tqdm(range(args.frames), desc="render"):
        w = sample_world(spec, spec.seed, i)
        out = render(w)
        frames.append((rendered_radiance(out.color, out.headroom), w.rig.intrinsics(), w.camera, i))
    if args.balance:
        find_balance(frames, spec.seed)
        return
    print(f"{args.spec}, {args.frames} frames; KITTI training set: mean {KITTI_MEAN.mean():.1f}, "
          f"SD {KITTI_SD.mean():.1f} (channel averages)")
    print("| key | gamma | mean R / G / B | SD R / G / B | mean | SD | saturation |")
    print("|---|---|---|---|---|---|---|")
    for gamma in args.gammas:
        for key in args.keys:
            imgs = [camera.expose(lin, K, dataclasses.replace(cam, gamma=gamma),
                                  factor_rng(spec.seed, i, "look"), key=key)
                    for lin, K, cam, i in frames]
            m, sd = pooled(imgs)
            print(f"| {key:.2f} | {gamma:.1f} | {' / '.join(f'{v:.1f}' for v in m)} | "
                  f"{' / '.join(f'{v:.1f}' for v in sd)} | {m.mean():.1f} | {sd.mean():.1f} | "
                  f"{saturation(imgs):.1f} |")


if __name__ == "__main__":
    main()
