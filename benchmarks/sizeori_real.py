"""Size and orientation network on the labelled objects of a KITTI root (made for the real dev
frames): the same crops and figures as training's validation (`lifter.train.errors`, `summary`: size MAE,
median alpha error, share within 30 degrees), for one or more weight files side by side, each
on the crops as seen and averaged with their mirror images (as `lifter.predictor` infers).
With more than one file, each after the first is also compared with it crop by crop (read with
the mirror): how many crops' alpha error grew or shrank by more than SHIFT_DEG, and the exact
two-sided sign test of those counts. `--by-view` splits the alpha errors (read with the mirror)
by class and by the side the camera sees (alpha within 45 deg of -90: from behind; of +90: from
in front; else from the side), with the share of crops read more than 90 deg off: a front read as
a back or the reverse.

    .venv/bin/python benchmarks/sizeori_real.py --data ../shared/kitti_real_dev \
        --weights lifter/weights/sizeori_mnv2_w050_s96.pt [--weights OTHER.pt ...] [--by-view]
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse

import numpy as np
import torch
from scipy.stats import binomtest

from kitti.dataset import KittiDataset
from lifter.multibin import wrap
from lifter.network import CLASSES
from lifter.predictor import load_network
from lifter.train import Samples, collect, errors, summary

SHIFT_DEG = 20.0  # a crop whose alpha error moves by more than this moved, not jittered
VIEWS = ("behind", "in front", "the side")


def views(alpha: np.ndarray) -> np.ndarray:
    """Index into VIEWS of each true alpha: the camera sees the object's back at alpha -90 deg,
    its front at +90 deg."""
    return np.where(np.abs(wrap(alpha + np.pi / 2)) < np.pi / 4, 0,
                    np.where(np.abs(wrap(alpha - np.pi / 2)) < np.pi / 4, 1, 2))


def by_view(samples: Samples, alpha_err: dict[str, np.ndarray]) -> None:
    """Median alpha error and share more than 90 deg off, per class and view, per weight file."""
    head = " | ".join(f"{p}: median / > 90 deg" for p in alpha_err)
    print(f"\nBy class and view (with mirror)\n\n| class | seen from | crops | {head} |")
    print("|---|---|---|" + "---|" * len(alpha_err))
    view = views(samples.alpha)
    for k, name in enumerate(CLASSES):
        for v, seen in enumerate(VIEWS):
            sel = (samples.cls == k) & (view == v)
            if sel.any():
                cells = " | ".join(f"{np.median(e[sel]):.1f} / {100 * np.mean(e[sel] > 90):.0f} %"
                                   for e in alpha_err.values())
                print(f"| {name} | {seen} | {sel.sum()} | {cells} |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default=None, help="ImageSets name (default: every frame)")
    ap.add_argument("--weights", action="append", required=True)
    ap.add_argument("--by-view", action="store_true", help="alpha errors by class and view")
    args = ap.parse_args()
    torch.set_num_threads(1)
    ds = KittiDataset(args.data)
    print(f"{args.data}: objects the network is trained on (classes, height, truncation and "
          "occlusion as in training)")
    print("| weights | crops | objects | size MAE (m) | alpha error, median (deg) | alpha within 30 deg |")
    print("|---|---|---|---|---|---|")
    alpha, crops = {}, {}  # crops: read once per crop size, shared by the files that use it
    for path in args.weights:
        net = load_network(path)
        if net.cfg.crop not in crops:
            crops[net.cfg.crop] = collect(ds, ds.ids(args.split), net.cfg.crop, "eval")
        samples = crops[net.cfg.crop]
        for mirror in (False, True):
            per_crop = errors(net, samples, net.cfg.crop, mirror=mirror)
            m = summary(*per_crop)
            print(f"| {path} | {'with mirror' if mirror else 'as seen'} | {m['n']} | "
                  f"{m['dims_mae_m']:.3f} | {m['alpha_median_deg']:.1f} | "
                  f"{100 * m['alpha_within_30deg']:.0f} % |")
        alpha[path] = per_crop[2]  # read with the mirror, as inference reads
    first, *others = args.weights
    if others:
        print(f"\nCrop by crop against {first} (with mirror): alpha error grown / shrunk by more "
              f"than {SHIFT_DEG:g} deg, exact two-sided sign test\n")
        print("| weights | grown | shrunk | sign test p |\n|---|---|---|---|")
    for path in others:
        moved = alpha[path] - alpha[first]
        grown, shrunk = int((moved > SHIFT_DEG).sum()), int((moved < -SHIFT_DEG).sum())
        p = binomtest(grown, grown + shrunk).pvalue if grown + shrunk else 1.0
        print(f"| {path} | {grown} | {shrunk} | {p:.3f} |")
    if args.by_view:  # the objects, their classes and alphas are the same at every crop size
        by_view(samples, alpha)


if __name__ == "__main__":
    main()
