"""How far the frames at hand decide a verdict. Eleven real frames give a median that another
eleven would move by more than the ±15 % tolerance on some statistics (the real dev frames'
share of ground returns left of the sensor is about 0.3 in six frames and 1.0 in four). Each
draw resamples both datasets' frames with replacement (a frame's objects and vectors travel
with it: they are not independent) and recomputes every statistic's relative difference; the
central 95 % of the draws bound it. Where it is known which frames share a drive
(`kitti.drives`), a draw resamples drives and takes all their frames (the bootstrap of clustered,
hierarchical data: Davison & Hinkley, "Bootstrap Methods and their Application", 1997): four of
the eleven real dev frames are one traffic jam seconds apart, the same cars in each, and drawn as
four independent frames they decide verdicts that their one street cannot. A verdict is decided
when that whole interval lies on the side of the tolerance the verdict is on, and undecided when
more frames could turn it.

The percentile bootstrap of a median (Efron & Tibshirani, "An Introduction to the Bootstrap",
1993, ch. 13) with a fixed seed, so the same inputs give the same report bytes."""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from kitti.drives import draw_units, drive_units
from kitti.eval.bootstrap import DRAWS, LEVEL, SEED, central_interval

from .catalog import STATS, Stat
from .stats import DatasetStats, Draws

# A statistic that cannot be evaluated (no object in its bin) in more draws than this share gets
# no interval.
MAX_UNDEFINED = 1.0 - LEVEL


@dataclass(frozen=True)
class Interval:
    """The central LEVEL share of the bootstrap draws of a relative difference
    (kitti.eval.bootstrap.central_interval: a draw where real is 0 and sim is not counts as
    +-inf)."""

    lo: float
    hi: float

    def decides(self, verdict: str, tolerance: float) -> bool:
        """Whether every difference in the interval gives `verdict` ('pass' or 'fail')."""
        if verdict == "pass":
            return -tolerance <= self.lo and self.hi <= tolerance
        if verdict == "fail":
            return self.lo > tolerance or self.hi < -tolerance
        return False


def relative_difference(sim: float, real: float) -> float:
    """(sim - real) / |real|; 0 where both are 0, +-inf where only real is 0, nan where either
    is undefined."""
    if math.isnan(sim) or math.isnan(real):
        return float("nan")
    if real == 0:
        return 0.0 if sim == 0 else math.copysign(math.inf, sim)
    return (sim - real) / abs(real)


def intervals(sim: DatasetStats, real: DatasetStats, draws: int = DRAWS, seed: int = SEED,
              stats: tuple[Stat, ...] = STATS, sim_drives: Mapping[str, str] | None = None,
              real_drives: Mapping[str, str] | None = None) -> dict[str, Interval | None]:
    """Each statistic's bootstrap interval of the relative difference (None: not enough frames,
    no draws, or undefined in too many draws); `*_drives` ({frame id: drive}) make the draws
    resample drives."""
    if draws <= 0 or not sim.frames or not real.frames:
        return {s.key: None for s in stats}
    rng = np.random.default_rng(seed)
    su, ru = drive_units(sim.frames, sim_drives), drive_units(real.frames, real_drives)
    picks = [(draw_units(rng, su), draw_units(rng, ru)) for _ in range(draws)]
    a, b = Draws.of(sim, [p for p, _ in picks]), Draws.of(real, [q for _, q in picks])
    rel = np.empty((draws, len(stats)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # medians of empty bins: nan
        for j, s in enumerate(stats):
            rel[:, j] = [relative_difference(x, y)
                         for x, y in zip(s.value.draws(a).tolist(), s.value.draws(b).tolist())]
    out: dict[str, Interval | None] = {}
    for j, s in enumerate(stats):
        col = rel[:, j][~np.isnan(rel[:, j])]
        out[s.key] = Interval(*central_interval(col)) if len(col) >= (1 - MAX_UNDEFINED) * draws else None
    return out
