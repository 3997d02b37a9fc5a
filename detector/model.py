"""FlexiNet: a one-stage, three-scale anchor detector whose depth and width scale by two
multiples (thesis 000, eq. 4.1): blocks per stage x depth_multiple, channels x width_multiple.

Layout: Focus stem -> 4 down-sampling stages with CSP blocks -> SPP(5, 9, 13) -> FPN (top-down)
+ PAN (bottom-up) neck -> one 1x1 prediction conv per scale (strides 8, 16, 32).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from detector.layers import ACTIVATIONS, CSPBlock, ConvUnit, Focus, SPP, fuse_model

STRIDES = (8, 16, 32)

# name -> (depth_multiple, width_multiple). "small" trains on a CPU; "s" is the thesis's best
# 3-class setting; "vehicle" its vehicle-only setting.
PRESETS: dict[str, tuple[float, float]] = {
    "small": (0.33, 0.25),
    "s": (0.33, 0.50),
    "vehicle": (0.55, 0.55),
}

# Base (multiple 1.0) channels and CSP repeats of the reference layout.
_BASE_CH = (64, 128, 256, 512, 1024)
_BASE_N = (3, 9, 9, 3)


@dataclass(frozen=True)
class ModelConfig:
    """Everything needed to rebuild the network (stored in checkpoints)."""
    num_classes: int = 3
    depth_multiple: float = 0.33
    width_multiple: float = 0.25
    activation: str = "hardswish"
    anchors: tuple[tuple[float, float], ...] = ((10, 13), (16, 30), (33, 23), (30, 61), (62, 45),
                                                (59, 119), (116, 90), (156, 198), (373, 326))

    @staticmethod
    def from_preset(preset: str, **kw) -> "ModelConfig":
        if preset not in PRESETS:
            raise ValueError(f"unknown preset {preset!r}; choose one of {sorted(PRESETS)}")
        d, w = PRESETS[preset]
        return ModelConfig(depth_multiple=d, width_multiple=w, **kw)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["anchors"] = [list(a) for a in self.anchors]
        return d

    @staticmethod
    def from_dict(d: dict) -> "ModelConfig":
        d = dict(d)
        d["anchors"] = tuple(tuple(float(v) for v in a) for a in d["anchors"])
        return ModelConfig(**d)


def _ch(c: int, w: float) -> int:
    """Scaled channel count, rounded up to a multiple of 8 (efficient kernels)."""
    return int(math.ceil(c * w / 8) * 8)


def _n(n: int, d: float) -> int:
    return max(round(n * d), 1)


class DetectHead(nn.Module):
    """Per scale, a 1x1 conv to na x (4 box + 1 objectness + nc classes) raw outputs.

    Box decoding (on the grid of stride s, anchor (aw, ah) in input pixels):
    centre = (2 sigmoid(t_xy) - 0.5 + cell) * s, size = (2 sigmoid(t_wh))^2 * anchor.
    The bounded size keeps early training stable (no exp blow-up).
    """

    def __init__(self, num_classes: int, anchors: torch.Tensor, channels: tuple[int, int, int]):
        super().__init__()
        self.nc = num_classes
        self.no = num_classes + 5
        self.nl = len(STRIDES)
        self.na = anchors.shape[0] // self.nl
        self.register_buffer("anchors", anchors.float().reshape(self.nl, self.na, 2))  # pixels
        self.register_buffer("strides", torch.tensor(STRIDES, dtype=torch.float32))
        self.m = nn.ModuleList(nn.Conv2d(c, self.na * self.no, 1) for c in channels)
        self._init_biases()

    def _init_biases(self) -> None:
        """Start objectness near the prior of ~8 objects per 640x640 image, classes near uniform,
        so the first iterations are not spent unlearning a 0.5 objectness everywhere."""
        for conv, s in zip(self.m, STRIDES):
            b = conv.bias.detach().view(self.na, -1)
            b[:, 4] += math.log(8 / (640 / s) ** 2)
            b[:, 5:] += math.log(0.6 / (self.nc - 0.99)) if self.nc > 1 else 0.0
            conv.bias = nn.Parameter(b.view(-1))

    def forward(self, feats: list[torch.Tensor]) -> list[torch.Tensor]:
        """Raw outputs per scale, shaped (B, na, H, W, no)."""
        out = []
        for i, f in enumerate(feats):
            p = self.m[i](f)
            b, _, h, w = p.shape
            out.append(p.view(b, self.na, self.no, h, w).permute(0, 1, 3, 4, 2).contiguous())
        return out

    def decode(self, raw: list[torch.Tensor]) -> torch.Tensor:
        """(B, N, 5 + nc): boxes as centre x, y, w, h in input pixels, objectness, class scores."""
        outs = []
        for i, p in enumerate(raw):
            b, na, h, w, no = p.shape
            ys, xs = torch.meshgrid(torch.arange(h, dtype=p.dtype, device=p.device),
                                    torch.arange(w, dtype=p.dtype, device=p.device), indexing="ij")
            grid = torch.stack((xs, ys), -1).view(1, 1, h, w, 2)
            y = p.sigmoid()
            xy = (y[..., :2] * 2 - 0.5 + grid) * self.strides[i]
            wh = (y[..., 2:4] * 2) ** 2 * self.anchors[i].view(1, na, 1, 1, 2)
            outs.append(torch.cat((xy, wh, y[..., 4:]), -1).view(b, -1, no))
        return torch.cat(outs, 1)


class FlexiNet(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        if cfg.activation not in ACTIVATIONS:
            raise ValueError(f"unknown activation {cfg.activation!r}; choose one of {ACTIVATIONS}")
        if len(cfg.anchors) != 9:
            raise ValueError(f"FlexiNet needs 9 anchors (3 per scale), got {len(cfg.anchors)}")
        self.cfg = cfg
        a, w, d = cfg.activation, cfg.width_multiple, cfg.depth_multiple
        c = [_ch(x, w) for x in _BASE_CH]
        n = [_n(x, d) for x in _BASE_N]
        # backbone
        self.stem = Focus(3, c[0], 3, a)
        self.down1 = nn.Sequential(ConvUnit(c[0], c[1], 3, 2, a), CSPBlock(c[1], c[1], n[0], True, a))
        self.down2 = nn.Sequential(ConvUnit(c[1], c[2], 3, 2, a), CSPBlock(c[2], c[2], n[1], True, a))  # P3
        self.down3 = nn.Sequential(ConvUnit(c[2], c[3], 3, 2, a), CSPBlock(c[3], c[3], n[2], True, a))  # P4
        self.down4 = nn.Sequential(ConvUnit(c[3], c[4], 3, 2, a), SPP(c[4], c[4], (5, 9, 13), a),
                                   CSPBlock(c[4], c[4], n[3], False, a))  # P5
        # FPN: top-down
        self.lat5 = ConvUnit(c[4], c[3], 1, 1, a)
        self.fpn4 = CSPBlock(2 * c[3], c[3], n[3], False, a)
        self.lat4 = ConvUnit(c[3], c[2], 1, 1, a)
        self.fpn3 = CSPBlock(2 * c[2], c[2], n[3], False, a)
        # PAN: bottom-up
        self.down_p3 = ConvUnit(c[2], c[2], 3, 2, a)
        self.pan4 = CSPBlock(2 * c[2], c[3], n[3], False, a)
        self.down_p4 = ConvUnit(c[3], c[3], 3, 2, a)
        self.pan5 = CSPBlock(2 * c[3], c[4], n[3], False, a)
        self.up = nn.Upsample(scale_factor=2, mode="nearest")
        self.head = DetectHead(cfg.num_classes, torch.tensor(cfg.anchors), (c[2], c[3], c[4]))

    def forward(self, x: torch.Tensor) -> list[torch.Tensor]:
        if x.shape[-1] % 32 or x.shape[-2] % 32:
            raise ValueError(f"input height and width must be multiples of 32, got {tuple(x.shape[-2:])}")
        p3 = self.down2(self.down1(self.stem(x)))
        p4 = self.down3(p3)
        p5 = self.down4(p4)
        l5 = self.lat5(p5)
        f4 = self.fpn4(torch.cat((self.up(l5), p4), 1))
        l4 = self.lat4(f4)
        o3 = self.fpn3(torch.cat((self.up(l4), p3), 1))
        o4 = self.pan4(torch.cat((self.down_p3(o3), l4), 1))
        o5 = self.pan5(torch.cat((self.down_p4(o4), l5), 1))
        return self.head([o3, o4, o5])

    @torch.no_grad()
    def predict_raw(self, x: torch.Tensor) -> torch.Tensor:
        """Decoded predictions (B, N, 5 + nc) in input pixels."""
        return self.head.decode(self(x))

    def fuse(self) -> "FlexiNet":
        """Fold batch norms into convolutions for inference."""
        fuse_model(self)
        return self


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
