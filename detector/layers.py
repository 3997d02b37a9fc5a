"""FlexiNet building blocks (thesis 000, ch. 4): Focus stem, conv units, CSP blocks, SPP.

Every block takes its activation by name so that the thesis's activation study
(Hardswish, Swish/SiLU, Mish, FReLU) is a configuration switch, not a code change.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

ACTIVATIONS = ("hardswish", "silu", "swish", "mish", "frelu")


class FReLU(nn.Module):
    """Funnel ReLU: max(x, T(x)) with T a depth-wise 3x3 conv + BN (a spatial condition)."""

    def __init__(self, c: int):
        super().__init__()
        self.conv = nn.Conv2d(c, c, 3, 1, 1, groups=c, bias=False)
        self.bn = nn.BatchNorm2d(c)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.maximum(x, self.bn(self.conv(x)))


def make_activation(name: str, c: int) -> nn.Module:
    """The activation module for `name` (FReLU needs the channel count, the rest do not)."""
    if name == "hardswish":
        return nn.Hardswish()
    if name in ("silu", "swish"):
        return nn.SiLU()
    if name == "mish":
        return nn.Mish()
    if name == "frelu":
        return FReLU(c)
    raise ValueError(f"unknown activation {name!r}; choose one of {ACTIVATIONS}")


class ConvUnit(nn.Module):
    """Conv2d (no bias) -> BatchNorm -> activation, 'same' padding for odd kernels."""

    def __init__(self, c1: int, c2: int, k: int = 1, s: int = 1, act: str = "hardswish"):
        super().__init__()
        self.conv = nn.Conv2d(c1, c2, k, s, k // 2, bias=False)
        # momentum 0.1 (not YOLOv5's 0.03): with the few thousand steps a CPU run affords, slower
        # running statistics lag the weights and eval-mode outputs collapse (seen on toy runs)
        self.bn = nn.BatchNorm2d(c2, eps=1e-3, momentum=0.1)
        self.act = make_activation(act, c2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.act(self.bn(self.conv(x)))


class Focus(nn.Module):
    """Space-to-depth 2x (3 -> 12 channels at half resolution), then a conv unit."""

    def __init__(self, c1: int, c2: int, k: int = 3, act: str = "hardswish"):
        super().__init__()
        self.conv = ConvUnit(4 * c1, c2, k, 1, act)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.shape[-1] % 2 or x.shape[-2] % 2:
            raise ValueError(f"Focus needs even input height and width, got {tuple(x.shape[-2:])}")
        return self.conv(torch.cat(
            (x[..., ::2, ::2], x[..., 1::2, ::2], x[..., ::2, 1::2], x[..., 1::2, 1::2]), 1))


class Bottleneck(nn.Module):
    """1x1 then 3x3 conv, with a residual connection when shapes allow and it is asked for."""

    def __init__(self, c1: int, c2: int, shortcut: bool = True, act: str = "hardswish"):
        super().__init__()
        self.cv1 = ConvUnit(c1, c2, 1, 1, act)
        self.cv2 = ConvUnit(c2, c2, 3, 1, act)
        self.add = shortcut and c1 == c2

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.cv2(self.cv1(x))
        return x + y if self.add else y


class CSPBlock(nn.Module):
    """Cross-stage partial block: half the channels go through n bottlenecks, the other half
    bypass them; the two are concatenated and fused (the partial transition layer)."""

    def __init__(self, c1: int, c2: int, n: int = 1, shortcut: bool = True, act: str = "hardswish"):
        super().__init__()
        c_ = c2 // 2
        self.cv1 = ConvUnit(c1, c_, 1, 1, act)
        self.cv2 = ConvUnit(c1, c_, 1, 1, act)
        self.cv3 = ConvUnit(2 * c_, c2, 1, 1, act)
        self.m = nn.Sequential(*(Bottleneck(c_, c_, shortcut, act) for _ in range(n)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.cv3(torch.cat((self.m(self.cv1(x)), self.cv2(x)), 1))


class SPP(nn.Module):
    """Spatial pyramid pooling: stride-1 max pools of kernels (5, 9, 13) concatenated with the input."""

    def __init__(self, c1: int, c2: int, kernels: tuple[int, ...] = (5, 9, 13), act: str = "hardswish"):
        super().__init__()
        c_ = c1 // 2
        self.cv1 = ConvUnit(c1, c_, 1, 1, act)
        self.cv2 = ConvUnit(c_ * (len(kernels) + 1), c2, 1, 1, act)
        self.pools = nn.ModuleList(nn.MaxPool2d(k, 1, k // 2) for k in kernels)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.cv1(x)
        return self.cv2(torch.cat([x] + [p(x) for p in self.pools], 1))


def fuse_conv_bn(conv: nn.Conv2d, bn: nn.BatchNorm2d) -> nn.Conv2d:
    """One conv equal to conv followed by (eval-mode) batch norm: faster inference, same output.
    The scale is numpy's square root and division (correctly rounded on every CPU): ATen's
    float32 sqrt is MKL's vector maths, whose last bits follow the CPU."""
    fused = nn.Conv2d(conv.in_channels, conv.out_channels, conv.kernel_size, conv.stride,
                      conv.padding, groups=conv.groups, bias=True)
    var, gamma = bn.running_var.detach().numpy(), bn.weight.detach().numpy()
    scale = torch.from_numpy(gamma / np.sqrt(var + np.float32(bn.eps)))
    fused.weight.data.copy_(conv.weight.data * scale.reshape(-1, 1, 1, 1))
    b = conv.bias.data if conv.bias is not None else torch.zeros_like(bn.running_mean)
    fused.bias.data.copy_((b - bn.running_mean) * scale + bn.bias)
    return fused


def fuse_model(model: nn.Module) -> nn.Module:
    """Fold every BatchNorm that follows a conv into it (inference only)."""
    for m in model.modules():
        if isinstance(m, ConvUnit):
            m.conv = fuse_conv_bn(m.conv, m.bn)
            m.bn = nn.Identity()
        elif isinstance(m, FReLU):
            m.conv = fuse_conv_bn(m.conv, m.bn)
            m.bn = nn.Identity()
    return model

