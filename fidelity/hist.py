"""Fixed-bin histogram accumulators: the only per-value state kept while streaming frames, so
memory does not grow with the number of frames or points."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Hist:
    """Counts over `bins` equal bins on [lo, hi); values outside land in the end bins."""

    lo: float
    hi: float
    bins: int
    counts: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.counts is None:
            self.counts = np.zeros(self.bins, np.int64)

    @property
    def edges(self) -> np.ndarray:
        return np.linspace(self.lo, self.hi, self.bins + 1)

    def add(self, values: np.ndarray, weights: np.ndarray | None = None) -> None:
        """Count `values`, each `weights` times where given (how often that value occurs)."""
        v = np.asarray(values).ravel()
        width = (self.hi - self.lo) / self.bins
        if v.dtype == np.uint8 and self.lo == 0 and self.hi >= 256 and width == int(width):
            idx = v // np.uint8(width) if width > 1 else v  # exact and cheap for pixels
        else:  # clip in floating point: clipping the integer indices costs five times more
            x = (v - self.lo) * (1 / width)
            np.clip(x, 0, self.bins - 1, out=x)
            idx = x.astype(np.intp)
        counts = np.bincount(idx, weights, minlength=self.bins)[: self.bins]
        self.counts += counts if weights is None else counts.astype(np.int64)

    def merge(self, other: Hist) -> None:
        self.counts += other.counts

    def normalised(self) -> np.ndarray:
        total = self.counts.sum()
        return self.counts / total if total else np.zeros(self.bins)
