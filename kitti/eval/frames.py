"""All frames of an evaluation packed into flat arrays, so every later step is vectorised.

Objects of frame f are rows `start[f]:start[f+1]`, in file order (the devkit's matching is greedy
in that order, so it matters). Every truth/detection pair of a frame has a slot in flat pair arrays,
row-major per frame; the overlaps of all metrics are computed once into these slots and reused by
every class, difficulty, threshold and distance bin.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..labels import Object3D

PLACEHOLDER = -1000.0  # the format's "unknown location"


@dataclass
class Objects:
    """Columns of one kind of object (truth or detections) over all frames."""

    start: np.ndarray  # (F+1,) int64
    type: np.ndarray  # (N,) lower-case str
    bbox: np.ndarray  # (N, 4)
    truncated: np.ndarray
    occluded: np.ndarray
    alpha: np.ndarray
    box7: np.ndarray  # (N, 7) x, y, z, h, w, l, ry
    score: np.ndarray  # (N,) (0 for truth)

    @property
    def has_bev(self) -> np.ndarray:
        b = self.box7
        return (b[:, 0] != PLACEHOLDER) & (b[:, 2] != PLACEHOLDER) & (b[:, 4] > 0) & (b[:, 5] > 0)

    @property
    def has_3d(self) -> np.ndarray:
        b = self.box7
        return self.has_bev & (b[:, 1] != PLACEHOLDER) & (b[:, 3] > 0)

    @property
    def distance(self) -> np.ndarray:
        """Ground-plane (camera x-z) distance of the box location; inf where it is unknown."""
        return np.where(self.has_bev, np.hypot(self.box7[:, 0], self.box7[:, 2]), np.inf)


def _columns(frames: Sequence[Sequence[Object3D]], detections: bool, ids: Sequence[str]) -> Objects:
    objs = [o for f in frames for o in f]
    if detections:
        for fid, f in zip(ids, frames):
            for k, o in enumerate(f):
                if o.score is None:
                    raise ValueError(f"frame {fid}: detection {k + 1} ({o.type}) has no score")
    n = len(objs)
    return Objects(
        start=np.concatenate([[0], np.cumsum([len(f) for f in frames])]).astype(np.int64),
        type=np.array([o.type.lower() for o in objs], dtype=str),
        bbox=np.array([o.bbox for o in objs], dtype=float).reshape(n, 4),
        truncated=np.array([o.truncated for o in objs], dtype=float),
        occluded=np.array([o.occluded for o in objs], dtype=np.int64),
        alpha=np.array([o.alpha for o in objs], dtype=float),
        box7=np.array([(*o.location, o.h, o.w, o.l, o.rotation_y) for o in objs],
                      dtype=float).reshape(n, 7),
        score=np.array([o.score if detections else 0.0 for o in objs], dtype=float))


def _spans(start: np.ndarray, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of `frames` (indices, in that order, repeats allowed) of a per-frame layout with
    row offsets `start`: (the new start offsets, the old row of each new row)."""
    counts = np.diff(start)[frames]
    new_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    rows = np.repeat(start[frames] - new_start[:-1], counts) + np.arange(new_start[-1])
    return new_start, rows


def take_objects(o: Objects, frames: np.ndarray) -> tuple[Objects, np.ndarray]:
    """The objects of `frames` in that order (a frame taken twice counts twice), and the old row
    of each new row."""
    start, rows = _spans(o.start, frames)
    return Objects(start, o.type[rows], o.bbox[rows], o.truncated[rows], o.occluded[rows],
                   o.alpha[rows], o.box7[rows], o.score[rows]), rows


@dataclass
class Packed:
    ids: list[str]
    gt: Objects  # truth without DontCare
    dt: Objects
    dc: Objects  # DontCare regions
    pair_start: np.ndarray  # (F+1,) truth x detection slots per frame, row-major
    pair_gt: np.ndarray  # (P,) global truth index of each slot
    pair_dt: np.ndarray  # (P,) global detection index

    def take(self, frames: np.ndarray) -> tuple[Packed, np.ndarray, np.ndarray]:
        """The frames at indices `frames` (in that order, repeats allowed) as a Packed of their
        own, named by position as a bootstrap draw names them; with the old slot of each new pair
        slot and the old row of each new detection, so overlaps computed once index into it
        (what `pack` of the same frames would give, without reading any object again)."""
        gt, _ = take_objects(self.gt, frames)
        dt, dt_rows = take_objects(self.dt, frames)
        dc, _ = take_objects(self.dc, frames)
        pair_start, pair_gt, pair_dt = frame_pairs(gt.start, dt.start)
        _, slots = _spans(self.pair_start, frames)
        return (Packed([f"{k:06d}" for k in range(len(frames))], gt, dt, dc, pair_start, pair_gt,
                       pair_dt), slots, dt_rows)


def frame_pairs(a_start: np.ndarray, b_start: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (a, b) pair within each frame, row-major: (pair_start, a index, b index)."""
    na, nb = np.diff(a_start), np.diff(b_start)
    counts = na * nb
    pair_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    total = int(pair_start[-1])
    frame = np.repeat(np.arange(len(na)), counts)
    pos = np.arange(total) - pair_start[frame]
    nbf = nb[frame]
    return pair_start, a_start[frame] + pos // np.maximum(nbf, 1), b_start[frame] + pos % np.maximum(nbf, 1)


def pack(gt: Mapping[str, Sequence[Object3D]], dt: Mapping[str, Sequence[Object3D]]) -> Packed:
    """Every truth frame, in sorted id order; a frame missing from `dt` has no detections."""
    ids = sorted(gt)
    truth = [[o for o in gt[i] if o.type.lower() != "dontcare"] for i in ids]
    dc = [[o for o in gt[i] if o.type.lower() == "dontcare"] for i in ids]
    dets = [list(dt.get(i, ())) for i in ids]
    g, d = _columns(truth, False, ids), _columns(dets, True, ids)
    pair_start, pair_gt, pair_dt = frame_pairs(g.start, d.start)
    return Packed(ids, g, d, _columns(dc, False, ids), pair_start, pair_gt, pair_dt)
