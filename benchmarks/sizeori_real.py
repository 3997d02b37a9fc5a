"""Size and orientation network on the labelled objects of a KITTI root (made for the real dev
frames): the same crops and figures as training's validation (`lifter.train.evaluate`: size MAE,
median alpha error, share within 30 degrees), for one or more weight files side by side, each
on the crops as seen and averaged with their mirror images (as `lifter.predictor` infers).

    .venv/bin/python benchmarks/sizeori_real.py --data ../shared/kitti_real_dev \
        --weights lifter/weights/sizeori_mnv2_w050_s96.pt [--weights OTHER.pt ...]
"""

from __future__ import annotations

import argparse

import torch

from kitti.dataset import KittiDataset
from lifter.predictor import load_network
from lifter.train import collect, evaluate


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
    for path in args.weights:
        net = load_network(path)
        samples = collect(ds, ds.ids(args.split), net.cfg.crop, "eval")
        for mirror in (False, True):
            with torch.no_grad():
                m = evaluate(net, samples, net.cfg.crop, mirror=mirror)
            print(f"| {path} | {'with mirror' if mirror else 'as seen'} | {m['n']} | "
                  f"{m['dims_mae_m']:.3f} | {m['alpha_median_deg']:.1f} | "
                  f"{100 * m['alpha_within_30deg']:.0f} % |")


if __name__ == "__main__":
    main()
