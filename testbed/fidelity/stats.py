"""What one pass over a dataset keeps: per-frame (and per-object) scalars, a few per-frame
vectors (per ring, per class) and fixed-bin histograms. Workers fill an `Acc` per chunk of frames;
the chunks merge, in job order, into one `DatasetStats`. Every value and vector keeps the index of
the frame it came from, so a bootstrap can resample frames (`DatasetStats.resample`) with each
frame's objects travelling together."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .hist import Hist

# Fixed bins of every pooled histogram: key -> (lo, hi, bins).
HIST_BINS: dict[str, tuple[float, float, int]] = {
    "lidar.range_m": (0.0, 120.0, 120),
    "lidar.reflectance": (0.0, 1.0, 50),
    "images.grey": (0.0, 256.0, 64),
    "images.saturation": (0.0, 256.0, 64),
    "images.gradient": (0.0, 362.0, 181),
    "labels.distance_m": (0.0, 100.0, 50),
    "labels.occlusion": (0.0, 4.0, 4),
    "labels.truncation": (0.0, 1.0, 10),
    "labels.box_height_px": (0.0, 400.0, 40),
    "labels.proj_gap_px": (0.0, 20.0, 40),
}


@dataclass
class Acc:
    """One chunk's accumulators (picklable: it travels back from a worker)."""

    values: dict[str, list[np.ndarray]] = field(default_factory=dict)
    rows: dict[str, list[np.ndarray]] = field(default_factory=dict)
    hists: dict[str, Hist] = field(default_factory=dict)
    frames: list[str] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    value_frames: dict[str, list[np.ndarray]] = field(default_factory=dict)
    row_frames: dict[str, list[int]] = field(default_factory=dict)

    def _frame(self) -> int:
        """Index (in this chunk) of the frame being read: the last one appended to `frames`."""
        if not self.frames:
            raise RuntimeError("a value was put before its frame was appended to Acc.frames")
        return len(self.frames) - 1

    def put(self, key: str, values) -> None:
        """Per-frame scalar or per-object values of the frame being read."""
        v = np.atleast_1d(np.asarray(values, np.float64))
        self.values.setdefault(key, []).append(v)
        self.value_frames.setdefault(key, []).append(np.full(len(v), self._frame(), np.int64))

    def row(self, key: str, vector) -> None:
        """A fixed-length vector (per ring, per class) of the frame being read."""
        self.rows.setdefault(key, []).append(np.asarray(vector, np.float64))
        self.row_frames.setdefault(key, []).append(self._frame())

    def hist(self, key: str, values) -> None:
        if key not in self.hists:
            self.hists[key] = Hist(*HIST_BINS[key])
        self.hists[key].add(values)


@dataclass
class DatasetStats:
    """Everything compare() and the plots need about one dataset root."""

    root: str
    split: str | None
    frames: list[str]                 # ids read
    skipped: list[tuple[str, str]]    # (id, error naming the file)
    groups: dict[str, bool]           # lidar / images / labels present
    values: dict[str, np.ndarray]     # 1-D: per frame or per object
    rows: dict[str, np.ndarray]       # 2-D: frames x fixed length
    hists: dict[str, Hist]
    value_frames: dict[str, np.ndarray] = field(default_factory=dict)  # frame index of each value
    row_frames: dict[str, np.ndarray] = field(default_factory=dict)    # frame index of each row

    def get(self, key: str) -> np.ndarray:
        """The values of `key`; empty when the group is absent or nothing was seen."""
        return self.values.get(key, np.zeros(0))

    def resample(self, picks: np.ndarray) -> DatasetStats:
        """The values and rows of the frames `picks` (indices into `frames`, repeats allowed), in
        that order, each frame with all its values: one bootstrap draw. Histograms are not
        resampled (no statistic reads them)."""
        picks = np.asarray(picks, np.int64)
        values, value_frames = _pick(self.values, self.value_frames, picks, len(self.frames))
        rows, row_frames = _pick(self.rows, self.row_frames, picks, len(self.frames))
        return DatasetStats(self.root, self.split, [self.frames[i] for i in picks], [], self.groups,
                            values, rows, self.hists, value_frames, row_frames)


def _pick(arrays: dict[str, np.ndarray], frame_of: dict[str, np.ndarray], picks: np.ndarray,
          n: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The entries of the picked frames, frame by frame, and their frame indices in the draw.
    Each key's frame indices never decrease, so each frame's entries are one run."""
    out, frames = {}, {}
    for k, a in arrays.items():
        starts = np.searchsorted(frame_of[k], np.arange(n + 1))
        counts = np.diff(starts)[picks]
        first = np.repeat(starts[picks] - np.cumsum(counts) + counts, counts)
        out[k] = a[first + np.arange(int(counts.sum()))]
        frames[k] = np.repeat(np.arange(len(picks)), counts)
    return out, frames


def merge(root: str, split: str | None, groups: dict[str, bool], parts: list[Acc]) -> DatasetStats:
    """Concatenate the chunks in order: the result does not depend on how frames were chunked."""
    values: dict[str, list[np.ndarray]] = {}
    rows: dict[str, list[np.ndarray]] = {}
    value_frames: dict[str, list[np.ndarray]] = {}
    row_frames: dict[str, list[int]] = {}
    hists: dict[str, Hist] = {k: Hist(*b) for k, b in HIST_BINS.items()}
    frames: list[str] = []
    skipped: list[tuple[str, str]] = []
    for p in parts:
        first = len(frames)  # the chunk's frame indices, shifted to the whole dataset's
        for k, v in p.values.items():
            values.setdefault(k, []).extend(v)
            value_frames.setdefault(k, []).extend(f + first for f in p.value_frames[k])
        for k, v in p.rows.items():
            rows.setdefault(k, []).extend(v)
            row_frames.setdefault(k, []).extend(f + first for f in p.row_frames[k])
        for k, h in p.hists.items():
            hists[k].merge(h)
        frames += p.frames
        skipped += p.skipped
    return DatasetStats(root, split, frames, skipped, groups,
                        {k: np.concatenate(v) for k, v in values.items()},
                        {k: np.stack(v) for k, v in rows.items()}, hists,
                        {k: np.concatenate(v) for k, v in value_frames.items()},
                        {k: np.array(v, np.int64) for k, v in row_frames.items()})
