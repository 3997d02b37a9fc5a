"""A uniform "model soup" of FlexiNet checkpoints: every floating-point tensor (weights and
BatchNorm statistics) averaged over weight files fine-tuned from one starting file.

Averaging the weights of fine-tunes that share their start (Wortsman et al. 2022, "Model soups")
often reads shifted data better than any one of them. The shipped detector weights are such an
average of two files (`detector/weights/README.md`).

    .venv/bin/python benchmarks/detector_soup.py --out runs/soup.pt \
        detector/weights/flexinet_small.pt runs/a/weights.pt runs/b/weights.pt ...
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
from pathlib import Path

import torch

from kitti.io import atomic_path


def soup(paths: list[Path]) -> dict:
    """The first checkpoint with its float tensors replaced by the mean over all of them (integer
    counters, such as BatchNorm's batches seen, kept from the first)."""
    cks = [torch.load(p, map_location="cpu", weights_only=True) for p in paths]
    first = cks[0]
    for p, ck in zip(paths[1:], cks[1:]):
        if ck["model_cfg"] != first["model_cfg"] or ck["input_size"] != first["input_size"]:
            raise ValueError(f"{p}: another network or input size than {paths[0]}")
    state = {k: (torch.stack([ck["model"][k].double() for ck in cks]).mean(0).to(v.dtype)
                 if v.is_floating_point() else v.clone()) for k, v in first["model"].items()}
    return {**first, "model": state, "soup_of": [str(p) for p in paths]}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("weights", nargs="+", type=Path)
    ap.add_argument("--out", required=True, type=Path)
    args = ap.parse_args()
    with atomic_path(args.out) as tmp:
        torch.save(soup(args.weights), tmp)
    print(f"{args.out}: the mean of {len(args.weights)} weight files")


if __name__ == "__main__":
    main()
