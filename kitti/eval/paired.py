"""Each truth object scored under two result sets, paired: how a change of sensor or method moves
the very same objects, with its interval over bootstrap draws of the frames.

Where the images and labels stay and only the LiDAR or the lifter changes (a sweep), every truth
object is scored at every point: the 3D IoU of the result box that claims it. Differences object
by object cancel what the objects share (a far, occluded car is hard at every point), so they
settle much smaller effects than two APs side by side. Their interval comes from draws of the
frames (`bootstrap.draw_frames`: a frame's objects together, a drive's frames together), the
same draws an AP's interval takes.

A result box claims a truth object by its 2D box, the one thing a lifter takes in and a change of
LiDAR never moves: pairs of the class overlapping by at least MIN_2D_OVERLAP, best first, one to
one (with the labels' own 2D boxes each lifted box claims its label). An object no box claims
scores IoU 0 at that point: a point that loses objects is not spared them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..labels import Object3D
from .bootstrap import central_interval
from .breakdown import _greedy
from .frames import pack
from .overlaps import pair_overlaps
from .protocol import clean

MIN_2D_OVERLAP = 0.5  # as benchmarks/beam_trend_paired.py; KITTI's Car 2D AP asks 0.7


@dataclass(frozen=True)
class TruthOverlaps:
    """The truth objects of one class evaluated at one difficulty, in frame and file order: each
    one's frame (index into `ids`, sorted), ground distance (m) and 3D IoU with the result box
    that claims it (0 where none does)."""

    ids: list[str]
    frame: np.ndarray
    distance: np.ndarray
    iou: np.ndarray

    def same_truth(self, other: TruthOverlaps) -> bool:
        """Whether both score the same objects (a pairing needs that)."""
        return (self.ids == other.ids and np.array_equal(self.frame, other.frame)
                and np.array_equal(self.distance, other.distance))


def truth_overlaps(gt: Mapping[str, Sequence[Object3D]], dt: Mapping[str, Sequence[Object3D]],
                   cls: str, difficulty: int = 1) -> TruthOverlaps:
    """Every truth object of `cls` that the evaluation counts at `difficulty` (0 easy, 1
    moderate, 2 hard; the neighbouring class, such as Van for Car, left out), scored against `dt`
    (module docstring)."""
    p = pack(gt, dt)
    c, g, d = cls.lower(), p.pair_gt, p.pair_dt
    ov2, ov3 = pair_overlaps(p, "2d"), pair_overlaps(p, "3d")
    k = np.nonzero((p.gt.type[g] == c) & (p.dt.type[d] == c) & (ov2 >= MIN_2D_OVERLAP))[0]
    k = k[np.lexsort((k, -ov2[k]))]  # best first, ties in file order
    k = k[_greedy(g[k], d[k], len(p.gt.type), len(p.dt.type))]
    iou = np.zeros(len(p.gt.type))
    iou[g[k]] = ov3[k]
    ig_gt, _ = clean(cls, difficulty, p.gt.type, p.gt.bbox, p.gt.occluded, p.gt.truncated,
                     p.dt.type, p.dt.bbox)
    rows = np.nonzero((ig_gt == 0) & (p.gt.type == c))[0]
    frame = np.searchsorted(p.gt.start, rows, side="right") - 1
    return TruthOverlaps(p.ids, frame, p.gt.distance[rows], iou[rows])


def frame_counts(draws: np.ndarray | Sequence[np.ndarray], frames: int) -> np.ndarray:
    """(draws, frames): how often each frame is taken by each draw of `bootstrap.draw_frames`."""
    return np.stack([np.bincount(picks, minlength=frames) for picks in draws])


@dataclass(frozen=True)
class Change:
    """The mean per-object change over `n` objects and its central 95 % over the draws (None
    without objects); decided where that interval leaves out zero."""

    n: int
    mean: float | None
    lo: float | None
    hi: float | None

    @property
    def decided(self) -> bool:
        return self.n > 0 and (self.lo > 0 or self.hi < 0)


def paired_change(after: np.ndarray, before: np.ndarray, frame: np.ndarray,
                  counts: np.ndarray) -> Change:
    """Mean of `after - before` (per object; `frame` their frames) and its interval over the
    draws `counts` (`frame_counts`): each draw's mean over the objects it takes, a frame taken
    twice counting twice, draws that take none of them left out."""
    if not len(frame):
        return Change(0, None, None, None)
    d = np.asarray(after, dtype=float) - np.asarray(before, dtype=float)
    w = counts[:, frame].astype(float)
    taken = w.sum(axis=1)
    lo, hi = central_interval((w @ d)[taken > 0] / taken[taken > 0])
    return Change(len(d), float(d.mean()), lo, hi)
