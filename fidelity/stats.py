"""What one pass over a dataset keeps: per-frame (and per-object) scalars, a few per-frame
vectors (per ring, per class) and fixed-bin histograms. Workers fill an `Acc` per chunk of frames;
the chunks merge, in job order, into one `DatasetStats`. Every value and vector keeps the index of
the frame it came from, so a bootstrap can resample frames (`DatasetStats.resample`; `Draws`, every
draw at once) with each frame's objects travelling together."""

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

    def hist(self, key: str, values, weights=None) -> None:
        if key not in self.hists:
            self.hists[key] = Hist(*HIST_BINS[key])
        self.hists[key].add(values, weights)


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

    def frames_of(self, key: str) -> np.ndarray:
        """The frame index of each value of `key` (aligned with `get`)."""
        return self.value_frames.get(key, np.zeros(0, np.int64))

    def resample(self, picks: np.ndarray) -> DatasetStats:
        """The values and rows of the frames `picks` (indices into `frames`, repeats allowed), in
        that order, each frame with all its values: one bootstrap draw. Histograms are not
        resampled (no statistic reads them)."""
        picks = np.asarray(picks, np.int64)
        values, value_frames = _pick(self.values, self.value_frames, picks, len(self.frames))
        rows, row_frames = _pick(self.rows, self.row_frames, picks, len(self.frames))
        return DatasetStats(self.root, self.split, [self.frames[i] for i in picks], [], self.groups,
                            values, rows, self.hists, value_frames, row_frames)


# Entries (draws x columns x values) that Draws.medians handles at once: bounds its memory.
BLOCK = 1 << 20


@dataclass
class Draws:
    """Every bootstrap draw of one dataset's frames at once, as counts: `counts[d, f]` is how often
    draw d picks frame f. A median per draw then comes from the dataset's own values, sorted once
    and each weighted by its frame's count, instead of a `resample` and a sort per draw. It is the
    mean of the same one or two order statistics, so the same number; only a -0.0 median may keep
    its sign where np.median's gives 0.0, which no relative difference sees."""

    stats: DatasetStats
    counts: np.ndarray  # (draws, frames), int32
    _columns: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def of(cls, stats: DatasetStats, picks: list[np.ndarray]) -> Draws:
        """The draws `picks` (each: indices into `stats.frames`, as for `resample`)."""
        n = len(stats.frames)
        return cls(stats, np.array([np.bincount(p, minlength=n) for p in picks], np.int32))

    def drawn(self, frames: np.ndarray) -> np.ndarray:
        """Per draw, how many of the entries belonging to `frames` it holds."""
        return self.counts[:, frames].sum(axis=1)

    def medians(self, values: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """Per draw (and per column of 2-D `values`, entries x columns), the median of the non-NaN
        entries, each counted as often as its frame (`frames`, one per entry) is drawn; NaN where
        a draw holds none."""
        cols = (values[:, None] if values.ndim == 1 else values).T  # columns x entries
        out = np.full((len(self.counts), len(cols)), np.nan)
        if not cols.size:
            return out.reshape((len(self.counts),) + values.shape[1:])
        order = np.argsort(cols, axis=1)  # NaN last, where no median reaches
        v, f = np.take_along_axis(cols, order, axis=1), frames[order]
        last = np.count_nonzero(~np.isnan(v), axis=1) - 1  # per column: its last non-NaN entry
        c = np.arange(len(cols))
        step = max(1, BLOCK // cols.size)
        for s in range(0, len(self.counts), step):
            cum = np.cumsum(np.take(self.counts[s:s + step], f, axis=1), axis=2, dtype=np.int32)
            n = np.where(last >= 0, cum[:, c, np.maximum(last, 0)], 0)  # non-NaN entries drawn
            # the order statistics (n - 1) // 2 and n // 2 of a draw: the first entries whose
            # cumulative count passes them (argmax stops at the first)
            lo = np.argmax(cum > ((n - 1) // 2)[..., None], axis=2)
            hi = np.argmax(cum > (n // 2)[..., None], axis=2)
            out[s:s + step] = np.where(n > 0, (v[c, lo] + v[c, hi]) / 2, np.nan)
        return out.reshape((len(self.counts),) + values.shape[1:])

    def column_medians(self, key: str) -> np.ndarray:
        """`medians` of each column of the rows of `key` (draws x columns), kept: two statistics
        read each key's."""
        if key not in self._columns:
            self._columns[key] = self.medians(self.stats.rows[key], self.stats.row_frames[key])
        return self._columns[key]

    def shares(self, passed: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """Per draw, the share of entries that `passed` (one bool per entry); NaN where a draw
        holds none."""
        n = len(self.stats.frames)
        total = self.counts @ np.bincount(frames, minlength=n)
        hits = self.counts @ np.bincount(frames[passed], minlength=n)
        return np.where(total > 0, hits / np.maximum(total, 1), np.nan)


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
