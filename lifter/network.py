"""Size and orientation network (000): a MobileNetV2-style backbone (inverted residual blocks with
linear bottlenecks, width multiplier) on the 2D crop, and three heads: dimensions as residuals from
the class means, MultiBin confidences and MultiBin (cos, sin) offsets.

Loss (000, Eq. 5.1): L = L_size + 6.0 * L_orient + 3.0 * L_conf.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import torch
from torch import nn
from torch.nn import functional as F

from .multibin import N_BINS, orientation_loss

CLASSES = ("Car", "Pedestrian", "Cyclist", "Van", "Truck")
# label type -> network class. Van and Truck keep their own means: folded into Car they bias every
# car's size up (a detector's "Car" box, van or not, is lifted as a Car).
CLASS_OF = {"Car": 0, "Pedestrian": 1, "Person_sitting": 1, "Cyclist": 2, "Van": 3, "Truck": 4,
            "Tram": 4}
W_ORIENT, W_CONF = 6.0, 3.0

# MobileNetV2's stages: expansion t, channels c, repeats n, first stride s
_STAGES = ((1, 16, 1, 1), (6, 24, 2, 2), (6, 32, 3, 2), (6, 64, 4, 2), (6, 96, 3, 1),
           (6, 160, 3, 2), (6, 320, 1, 1))


def _div8(v: float) -> int:
    """Round channels to a multiple of 8, never below 90 % of v (MobileNetV2's rule)."""
    new = max(8, int(v + 4) // 8 * 8)
    return new + 8 if new < 0.9 * v else new


@dataclass
class NetConfig:
    width: float = 0.5
    crop: int = 224
    last_channels: int = 640
    hidden: int = 256
    class_means: list[list[float]] = field(default_factory=lambda: [[1.53, 1.63, 3.88],
                                                                    [1.76, 0.66, 0.84],
                                                                    [1.74, 0.60, 1.76],
                                                                    [2.21, 1.90, 5.08],
                                                                    [3.25, 2.59, 10.1]])

    def to_dict(self) -> dict:
        return asdict(self)


class InvertedResidual(nn.Module):
    """1x1 expand -> 3x3 depthwise -> 1x1 linear projection; identity shortcut when shapes match."""

    def __init__(self, cin: int, cout: int, stride: int, expand: int):
        super().__init__()
        mid = cin * expand
        layers: list[nn.Module] = []
        if expand != 1:
            layers += [nn.Conv2d(cin, mid, 1, bias=False), nn.BatchNorm2d(mid), nn.ReLU6(inplace=True)]
        layers += [nn.Conv2d(mid, mid, 3, stride, 1, groups=mid, bias=False), nn.BatchNorm2d(mid),
                   nn.ReLU6(inplace=True), nn.Conv2d(mid, cout, 1, bias=False), nn.BatchNorm2d(cout)]
        self.body = nn.Sequential(*layers)
        self.residual = stride == 1 and cin == cout

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.body(x) if self.residual else self.body(x)


class SizeOrientationNet(nn.Module):
    def __init__(self, cfg: NetConfig):
        super().__init__()
        self.cfg = cfg
        c = _div8(32 * cfg.width)
        layers: list[nn.Module] = [nn.Conv2d(3, c, 3, 2, 1, bias=False), nn.BatchNorm2d(c),
                                   nn.ReLU6(inplace=True)]
        for t, ch, n, s in _STAGES:
            out = _div8(ch * cfg.width)
            for i in range(n):
                layers.append(InvertedResidual(c, out, s if i == 0 else 1, t))
                c = out
        layers += [nn.Conv2d(c, cfg.last_channels, 1, bias=False), nn.BatchNorm2d(cfg.last_channels),
                   nn.ReLU6(inplace=True)]
        self.features = nn.Sequential(*layers)
        k = len(CLASSES)
        self.neck = nn.Sequential(nn.Dropout(0.2), nn.Linear(cfg.last_channels, cfg.hidden),
                                  nn.ReLU(inplace=True))
        self.dims = nn.Linear(cfg.hidden, 3 * k)
        self.conf = nn.Linear(cfg.hidden, N_BINS)
        self.orient = nn.Linear(cfg.hidden, 2 * N_BINS)
        self.register_buffer("means", torch.tensor(cfg.class_means, dtype=torch.float32))

    def forward(self, x: torch.Tensor, cls: torch.Tensor):
        """x (N,3,S,S) normalised crops, cls (N,) class index -> dims (N,3) metres, conf logits
        (N,B), offsets (N,B,2)."""
        f = self.neck(F.adaptive_avg_pool2d(self.features(x), 1).flatten(1))
        res = self.dims(f).view(-1, len(CLASSES), 3)[torch.arange(len(cls)), cls]
        return self.means[cls] + res, self.conf(f), self.orient(f).view(-1, N_BINS, 2)


def loss_fn(out, dims_t, bin_t, cs_t, cover_t) -> tuple[torch.Tensor, dict[str, float]]:
    dims, conf, cs = out
    l_size = F.mse_loss(dims, dims_t)
    l_orient = orientation_loss(cs, cs_t, cover_t)
    l_conf = F.cross_entropy(conf, bin_t)
    total = l_size + W_ORIENT * l_orient + W_CONF * l_conf
    parts = {"size": l_size.item(), "orient": l_orient.item(), "conf": l_conf.item()}
    return total, parts
