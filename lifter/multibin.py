"""MultiBin orientation (Deep3DBox, 003; two bins as in 000): the local orientation alpha is a bin
plus an offset from its centre, so the network never regresses across the -pi/pi seam.

Two bins centred at -90 and +90 degrees, each covering its half circle plus OVERLAP/2 on either
side (the thesis: "two proposals in the intervals (0, -179) and (1, 180)"; the overlap is not given,
30 degrees chosen so that an angle near a boundary trains both bins' offsets).
"""

from __future__ import annotations

import numpy as np
import torch

N_BINS = 2
CENTRES = np.array([-np.pi / 2, np.pi / 2])
OVERLAP = np.deg2rad(30.0)
HALF_COVER = np.pi / N_BINS + OVERLAP / 2


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def encode(alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Targets for angles (N,): best bin (N,), per-bin offset (cos, sin) (N, B, 2), cover mask (N, B)."""
    alpha = np.asarray(alpha, dtype=float).reshape(-1)
    delta = wrap(alpha[:, None] - CENTRES[None, :])  # (N, B)
    best = np.argmin(np.abs(delta), axis=1)
    cover = np.abs(delta) <= HALF_COVER
    return best, np.stack([np.cos(delta), np.sin(delta)], axis=2), cover


def decode(conf_logits: np.ndarray, cos_sin: np.ndarray) -> np.ndarray:
    """Angles (N,) from conf logits (N, B) and offsets (N, B, 2) (need not be unit length)."""
    b = np.argmax(conf_logits, axis=1)
    cs = cos_sin[np.arange(len(b)), b]
    return wrap(CENTRES[b] + np.arctan2(cs[:, 1], cs[:, 0]))


def orientation_loss(cos_sin: torch.Tensor, target: torch.Tensor, cover: torch.Tensor) -> torch.Tensor:
    """L2 between the unit offset predicted and the true (cos, sin), over the bins that cover the
    angle (|u - v|^2 = 2 - 2 cos(error) for unit vectors)."""
    unit = torch.nn.functional.normalize(cos_sin, dim=-1)
    err = ((unit - target) ** 2).sum(-1)  # (N, B)
    m = cover.float()
    return (err * m).sum() / m.sum().clamp(min=1.0)
