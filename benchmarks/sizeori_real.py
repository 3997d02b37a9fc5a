"""Size and orientation network on the labelled objects of a KITTI root (made for the real dev
frames): the same crops and figures as training's validation (`lifter.train.errors`, `summary`: size MAE,
median alpha error, share within 30 degrees), for one or more weight files side by side, each
on the crops as seen and averaged with their mirror images (as `lifter.predictor` infers).
With more than one file, each after the first is also compared with it crop by crop (read with
the mirror): how many crops' alpha error grew or shrank by more than SHIFT_DEG, and the exact
two-sided sign test of those counts.

    .venv/bin/python benchmarks/sizeori_real.py --data ../shared/kitti_real_dev \
        --weights lifter/weights/sizeori_mnv2_w050_s96.pt [--weights OTHER.pt ...]
"""

from __future__ import annotations

import argparse

import torch
from scipy.stats import binomtest

from kitti.dataset import KittiDataset
from lifter.predictor import load_network
from lifter.train import collect, errors, summary

SHIFT_DEG = 20.0  # a crop whose alpha error moves by more than this moved, not jittered


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", default=None, help="ImageSets name (default: every frame)")
    ap.add_argument("--weights", action="append", required=True)
    args = ap.parse_args()
    torch.set_num_threads(1)
    ds = KittiDataset(args.data)
    print(f"{args.data}: objects the network is trained on (classes, height, truncation and "
          "occlusion as in training)")
    print("| weights | crops | objects | size MAE (m) | alpha error, median (deg) | alpha within 30 deg |")
    print("|---|---|---|---|---|---|")
    alpha = {}
    for path in args.weights:
        net = load_network(path)
        samples = collect(ds, ds.ids(args.split), net.cfg.crop, "eval")
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


if __name__ == "__main__":
    main()
