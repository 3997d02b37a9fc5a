"""Training loss: an IoU-family box loss (DIoU by default, thesis 000 found it 1-2 % better than
GIoU), BCE-with-logits for objectness and classes.

Target assignment: a label is trained on every anchor whose width and height ratios to it are
both within `anchor_ratio` (4), in the cell holding its centre and in the two neighbouring cells
nearest to that centre (the decoded centre can reach -0.5..1.5 cells, so they can predict it).
Objectness targets are the (detached) IoU of the predicted box, so the score learns to rank by
localisation quality, which is what a 0.7-IoU AP rewards.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

from detector.boxes import aligned_iou, cxcywh_to_xyxy
from detector.model import STRIDES, DetectHead

BOX_LOSSES = ("diou", "giou", "ciou")
CONSISTENCY_TARGETS = ("mutual", "plain")


@dataclass(frozen=True)
class LossGains:
    box: float = 0.05
    obj: float = 1.0
    cls: float = 0.5
    anchor_ratio: float = 4.0
    balance: tuple[float, float, float] = (4.0, 1.0, 0.4)  # objectness weight per scale, fine to coarse


_OFFSETS = torch.tensor([[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1]], dtype=torch.float32)


class DetectionLoss:
    def __init__(self, head: DetectHead, box_loss: str = "diou", gains: LossGains = LossGains()):
        if box_loss not in BOX_LOSSES:
            raise ValueError(f"unknown box loss {box_loss!r}; choose one of {BOX_LOSSES}")
        self.head = head
        self.box_loss = box_loss
        self.g = gains
        self.bce = nn.BCEWithLogitsLoss()

    def build_targets(self, raw: list[torch.Tensor], targets: torch.Tensor):
        """targets (M,6): image index, class, cx, cy, w, h in input pixels. Per scale: the
        (image, anchor, row, col) of each positive sample, its class, and its box in grid units
        relative to the cell."""
        out = []
        na = self.head.na
        for i, p in enumerate(raw):
            _, _, h, w, _ = p.shape
            s = float(STRIDES[i])
            anchors = self.head.anchors[i] / s  # (na,2) grid units
            t = targets.clone()
            t[:, 2:6] /= s
            if t.shape[0] == 0:
                out.append(None)
                continue
            ratio = t[None, :, 4:6] / anchors[:, None, :]  # (na,M,2)
            ok = torch.maximum(ratio, 1 / ratio).max(2).values < self.g.anchor_ratio
            a_idx = torch.arange(na).view(na, 1).expand(na, t.shape[0])[ok]
            t = t[None].expand(na, -1, -1)[ok]
            gxy = t[:, 2:4]
            gxi = torch.tensor([w, h], dtype=gxy.dtype) - gxy
            j, k = ((gxy % 1 < 0.5) & (gxy > 1)).T
            l, m = ((gxi % 1 < 0.5) & (gxi > 1)).T
            sel = torch.stack((torch.ones_like(j), j, k, l, m))  # (5,n)
            t = t[None].expand(5, -1, -1)[sel]
            a_idx = a_idx[None].expand(5, -1)[sel]
            offsets = (_OFFSETS[:, None, :].expand(-1, sel.shape[1], -1) * 0.5)[sel]
            gxy = t[:, 2:4]
            gij = (gxy - offsets).long()
            gi = gij[:, 0].clamp(0, w - 1)
            gj = gij[:, 1].clamp(0, h - 1)
            tbox = torch.cat((gxy - torch.stack((gi, gj), 1).to(gxy.dtype), t[:, 4:6]), 1)
            out.append((t[:, 0].long(), a_idx, gj, gi, t[:, 1].long(), tbox, anchors[a_idx]))
        return out

    def __call__(self, raw: list[torch.Tensor], targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Total loss (scaled by batch size) and its (box, obj, cls) parts for logging."""
        bs = raw[0].shape[0]
        nc = self.head.nc
        lbox = raw[0].new_zeros(())
        lobj = raw[0].new_zeros(())
        lcls = raw[0].new_zeros(())
        cells = sum(p.shape[2] * p.shape[3] for p in raw)
        cells_640 = sum((640 // s) ** 2 for s in STRIDES)
        for i, (p, tgt) in enumerate(zip(raw, self.build_targets(raw, targets))):
            tobj = torch.zeros(p.shape[:4], dtype=p.dtype)
            if tgt is not None and tgt[0].numel():
                b, a, gj, gi, cls, tbox, anc = tgt
                ps = p[b, a, gj, gi]
                pxy = ps[:, :2].sigmoid() * 2 - 0.5
                pwh = (ps[:, 2:4].sigmoid() * 2) ** 2 * anc
                iou = aligned_iou(cxcywh_to_xyxy(torch.cat((pxy, pwh), 1)), cxcywh_to_xyxy(tbox), self.box_loss)
                lbox = lbox + (1.0 - iou).mean()
                tobj[b, a, gj, gi] = iou.detach().clamp(0).to(tobj.dtype)
                if nc > 1:
                    tc = torch.zeros_like(ps[:, 5:])
                    tc[torch.arange(len(cls)), cls] = 1.0
                    lcls = lcls + self.bce(ps[:, 5:], tc)
            lobj = lobj + self.bce(p[..., 4], tobj) * self.g.balance[i]
        lbox = lbox * self.g.box
        lobj = lobj * self.g.obj * cells / cells_640
        lcls = lcls * self.g.cls * nc / 80
        parts = torch.stack((lbox, lobj, lcls)).detach()
        return (lbox + lobj + lcls) * bs, parts

    def pair_consistency(self, raw: list[torch.Tensor], target: str = "mutual") -> torch.Tensor:
        """RandConv's consistency term for a batch of pairs (images 2k and 2k+1 are one sample seen
        plain and convolved): per cell, the Jensen-Shannon divergence between the two views'
        objectness probabilities ("mutual"), or the KL divergence from the plain view's, detached,
        to the convolved view's ("plain": the plain view is a fixed target and learns from the
        detection loss alone); weighted and scaled as the objectness loss is, times the batch size
        as the total loss is. Objectness only: it is the object/background decision that real
        frames get wrong (trees and facades fired on), and boxes and classes are already supervised
        identically on both views."""
        if target not in CONSISTENCY_TARGETS:
            raise ValueError(f"unknown consistency target {target!r}; choose one of {CONSISTENCY_TARGETS}")
        if raw[0].shape[0] % 2:
            raise ValueError(f"a batch of pairs needs an even number of images, got {raw[0].shape[0]}")
        total = raw[0].new_zeros(())
        for i, p in enumerate(raw):
            x = p[..., 4]
            d = bernoulli_js(x[0::2], x[1::2]) if target == "mutual" else bernoulli_kl(x[0::2].detach(), x[1::2])
            total = total + d.mean() * self.g.balance[i]
        cells = sum(p.shape[2] * p.shape[3] for p in raw)
        cells_640 = sum((640 // s) ** 2 for s in STRIDES)
        return total * self.g.obj * cells / cells_640 * raw[0].shape[0]


def bernoulli_js(xa: torch.Tensor, xb: torch.Tensor) -> torch.Tensor:
    """Element-wise Jensen-Shannon divergence (nats) between Bernoulli(sigmoid(xa)) and
    Bernoulli(sigmoid(xb)), from the logits in log space (no 0 * log 0 at saturated scores)."""
    la, lb = F.logsigmoid(xa), F.logsigmoid(xb)          # log p
    na, nb = F.logsigmoid(-xa), F.logsigmoid(-xb)        # log (1 - p)
    lm = torch.logaddexp(la, lb) - math.log(2.0)         # log of the mean probability
    nm = torch.logaddexp(na, nb) - math.log(2.0)
    return 0.5 * (_kl_from_logs(la, na, lm, nm) + _kl_from_logs(lb, nb, lm, nm))


def bernoulli_kl(xp: torch.Tensor, xq: torch.Tensor) -> torch.Tensor:
    """Element-wise KL(Bernoulli(sigmoid(xp)) || Bernoulli(sigmoid(xq))) in nats, from the logits."""
    return _kl_from_logs(F.logsigmoid(xp), F.logsigmoid(-xp), F.logsigmoid(xq), F.logsigmoid(-xq))


def _kl_from_logs(lp: torch.Tensor, np_: torch.Tensor, lq: torch.Tensor, nq: torch.Tensor) -> torch.Tensor:
    """KL(Bernoulli(p) || Bernoulli(q)) from log p, log (1 - p), log q, log (1 - q)."""
    return lp.exp() * (lp - lq) + np_.exp() * (np_ - nq)
