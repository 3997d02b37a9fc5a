"""Test-time batch-norm adaptation of a detector's weights (a diagnosis; not part of `testbed detect`).

AdaBN (Li et al. 2016, "Revisiting Batch Normalization For Practical Domain Adaptation"), the full
adaptation of Schneider et al. (NeurIPS 2020, "Improving robustness against common corruptions by
covariate shift adaptation"): every BatchNorm's statistics are estimated again on the frames being
detected, no label read, then the frames are detected as `testbed detect` does (letterboxed, read
as seen and mirrored). `--stats set` takes them over all the frames of the split (PyTorch's
cumulative average over one frame and its mirror at a time); `--stats image` over each frame
alone. Writes one KITTI result file per frame into --out, for `testbed evaluate`.

    .venv/bin/python benchmarks/detector_adabn.py --data ../shared/kitti_real_dev --out runs/adabn_real \
        [--weights W] [--split S] [--stats set|image]
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from detector.boxes import Letterbox
from detector.infer import DEFAULT_WEIGHTS, Detector
from detector.model import FlexiNet, ModelConfig
from kitti.dataset import KittiDataset
from kitti.labels import write_label


def network_input(image: np.ndarray, size: tuple[int, int]) -> torch.Tensor:
    """(2, 3, h, w): the letterboxed frame and its mirror, as `Detector.detect` feeds them."""
    x = torch.from_numpy(Letterbox.fit(image.shape[1], image.shape[0], *size).apply(image)[None])
    x = x.permute(0, 3, 1, 2).float().div_(255)
    return torch.cat([x, x.flip(-1)])


def adapted(checkpoint: dict, batches: Iterable[torch.Tensor]) -> FlexiNet:
    """The network with every BatchNorm's running statistics re-estimated on `batches`."""
    model = FlexiNet(ModelConfig.from_dict(checkpoint["model_cfg"]))
    model.load_state_dict(checkpoint["model"])
    model.eval()
    for bn in (m for m in model.modules() if isinstance(m, torch.nn.BatchNorm2d)):
        bn.reset_running_stats()
        bn.momentum = None  # a cumulative average over the batches
        bn.train()
    with torch.no_grad():
        for x in batches:
            model(x)
    return model.eval().fuse()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--weights", default=str(DEFAULT_WEIGHTS))
    ap.add_argument("--split", default=None)
    ap.add_argument("--stats", choices=("set", "image"), default="set")
    args = ap.parse_args()
    torch.set_num_threads(2)
    ck = torch.load(args.weights, map_location="cpu", weights_only=True)
    size, classes = tuple(ck["input_size"]), tuple(ck["classes"])
    ds = KittiDataset(args.data)
    ids = ds.ids(args.split)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.stats == "set":
        model = adapted(ck, (network_input(ds.image(f), size) for f in tqdm(ids, desc="statistics")))
        det = Detector((model,), size, classes, mirror=True)
    for fid in tqdm(ids, desc="detect"):
        image = ds.image(fid)
        if args.stats == "image":
            det = Detector((adapted(ck, [network_input(image, size)]),), size, classes, mirror=True)
        write_label(out / f"{fid}.txt", det.to_objects(det.detect([image])[0]))


if __name__ == "__main__":
    main()
