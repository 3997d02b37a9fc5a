"""What one pass over a dataset keeps: per-frame (and per-object) scalars, a few per-frame
vectors (per ring, per class) and fixed-bin histograms. Workers fill an `Acc` per chunk of frames;
the chunks merge, in job order, into one `DatasetStats`."""

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

    def put(self, key: str, values) -> None:
        """Per-frame scalar or per-object values."""
        self.values.setdefault(key, []).append(np.atleast_1d(np.asarray(values, np.float64)))

    def row(self, key: str, vector) -> None:
        """A fixed-length per-frame vector (per ring, per class)."""
        self.rows.setdefault(key, []).append(np.asarray(vector, np.float64))

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

    def get(self, key: str) -> np.ndarray:
        """The values of `key`; empty when the group is absent or nothing was seen."""
        return self.values.get(key, np.zeros(0))


def merge(root: str, split: str | None, groups: dict[str, bool], parts: list[Acc]) -> DatasetStats:
    """Concatenate the chunks in order: the result does not depend on how frames were chunked."""
    values: dict[str, list[np.ndarray]] = {}
    rows: dict[str, list[np.ndarray]] = {}
    hists: dict[str, Hist] = {k: Hist(*b) for k, b in HIST_BINS.items()}
    frames: list[str] = []
    skipped: list[tuple[str, str]] = []
    for p in parts:
        for k, v in p.values.items():
            values.setdefault(k, []).extend(v)
        for k, v in p.rows.items():
            rows.setdefault(k, []).extend(v)
        for k, h in p.hists.items():
            hists[k].merge(h)
        frames += p.frames
        skipped += p.skipped
    return DatasetStats(root, split, frames, skipped, groups,
                        {k: np.concatenate(v) for k, v in values.items()},
                        {k: np.stack(v) for k, v in rows.items()}, hists)
