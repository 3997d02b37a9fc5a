"""Size and orientation for 2D boxes from a trained network checkpoint."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import torch

from kitti.cpu import portable_networks

from .crops import crop, to_tensor_layout
from .multibin import decode
from .network import CLASS_OF, NetConfig, SizeOrientationNet
from .types import Box2D, Prior

DEFAULT_WEIGHTS = Path(__file__).parent / "weights" / "sizeori_mnv2_w050_s96.pt"


def load_network(path: str | Path) -> SizeOrientationNet:
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such lifter checkpoint (train one with "
                                f"`testbed train-lifter`)")
    ckpt = torch.load(path, map_location="cpu", weights_only=False)
    try:
        net = SizeOrientationNet(NetConfig(**ckpt["config"]))
        net.load_state_dict(ckpt["model"])
    except (KeyError, TypeError, RuntimeError) as exc:
        raise ValueError(f"{path}: not a lifter checkpoint ({exc})") from None
    return net.eval()


def forward_mirrored(net: SizeOrientationNet, x: torch.Tensor, cls: torch.Tensor, mirror: bool = True):
    """The network's outputs for crops x (N,3,S,S), averaged with those for the mirrored crops
    when `mirror`. The network was trained on crops mirrored half the time (alpha -> pi - alpha),
    and a mirror maps each MultiBin bin (centres -90 and +90 degrees) onto itself with its offset
    negated, so the two passes' bin logits, offsets (cos, -sin) and sizes average directly."""
    if not mirror:
        return net(x, cls)
    dims, conf, cs = net(torch.cat([x, x.flip(-1)]), torch.cat([cls, cls]))
    n = len(cls)
    cs_m = cs[n:] * torch.tensor([1.0, -1.0])
    return (dims[:n] + dims[n:]) / 2, (conf[:n] + conf[n:]) / 2, (cs[:n] + cs_m) / 2


class Predictor:
    """Batched inference: one forward pass per frame (the crops and their mirror images)."""

    def __init__(self, weights: str | Path = DEFAULT_WEIGHTS, threads: int | None = 1,
                 mirror: bool = True):
        """`threads`: torch's intra-op threads (None leaves them alone). One is fastest for a
        frame's dozen small crops, and far faster than two on a busy machine. `mirror`: average
        each crop's outputs with its mirror image's (`forward_mirrored`)."""
        if threads is not None:
            torch.set_num_threads(threads)
        self.net = load_network(weights)
        self.size = self.net.cfg.crop
        self.mirror = mirror
        # what the outputs depend on besides the image and the boxes: the weights' bytes, the mirror
        self.key = (hashlib.sha256(Path(weights).read_bytes()).hexdigest(), mirror)

    @torch.no_grad()
    def __call__(self, image: np.ndarray, boxes: list[Box2D]) -> list[Prior]:
        if not boxes:
            return []
        x = to_tensor_layout(np.stack([crop(image, b.bbox, self.size) for b in boxes]))
        cls = torch.tensor([CLASS_OF.get(b.type, 0) for b in boxes])
        with portable_networks():
            dims, conf, cs = forward_mirrored(self.net, torch.from_numpy(x), cls, self.mirror)
        alpha = decode(conf.numpy(), cs.numpy())
        return [Prior(d.astype(float), float(a)) for d, a in zip(dims.numpy(), alpha)]
