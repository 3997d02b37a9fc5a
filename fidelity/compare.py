"""Sim against real, statistic by statistic: the relative difference (sim - real) / |real|, a
pass/fail verdict against a per-statistic tolerance from tolerances.yaml, and whether the frames
at hand decide that verdict (bootstrap.py)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from kitti.drives import drive_units

from .bootstrap import DRAWS, Interval, intervals, relative_difference
from .catalog import STAT_KEYS, STATS
from .stats import DatasetStats

TOLERANCES_FILE = Path(__file__).with_name("tolerances.yaml")


class ToleranceError(ValueError):
    """A tolerance file that does not validate; the message names the file and the key."""


class Tolerances(BaseModel):
    """Relative tolerances: `default` for every statistic not named under `statistics`."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    default: float = Field(0.15, gt=0)
    statistics: dict[str, float] = Field(default_factory=dict)

    @field_validator("statistics")
    @classmethod
    def _known(cls, v: dict[str, float]) -> dict[str, float]:
        for key, tol in v.items():
            if key not in STAT_KEYS:
                raise ValueError(f"unknown statistic '{key}' (known: {', '.join(sorted(STAT_KEYS))})")
            if not tol > 0:
                raise ValueError(f"tolerance of '{key}' must be > 0, got {tol}")
        return v

    def of(self, key: str) -> float:
        return self.statistics.get(key, self.default)


def load_tolerances(path: str | Path | None = None) -> Tolerances:
    """The shipped tolerances.yaml, or `path`."""
    path = Path(path) if path is not None else TOLERANCES_FILE
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except OSError as e:
        raise ToleranceError(f"{path}: cannot read the tolerances: {e.strerror}") from None
    except yaml.YAMLError as e:
        raise ToleranceError(f"{path}: not valid YAML: {e}") from None
    try:
        return Tolerances.model_validate(data)
    except ValidationError as e:
        raise ToleranceError("\n".join(
            f"{path}: key '{'.'.join(str(p) for p in err['loc']) or '<top level>'}': "
            f"{err['msg'].removeprefix('Value error, ')}" for err in e.errors())) from None


@dataclass(frozen=True)
class Row:
    key: str
    label: str
    unit: str
    sim: float
    real: float
    rel_diff: float | None  # None: real is 0 and sim is not
    tolerance: float
    verdict: str            # pass, fail, or n/a (a group absent or no data)
    interval: Interval | None = None  # 95 % bootstrap interval of rel_diff (frames or drives resampled)

    @property
    def decided(self) -> bool | None:
        """Whether the whole interval gives the verdict (None: no interval, or no verdict)."""
        if self.interval is None or self.verdict == "n/a":
            return None
        return self.interval.decides(self.verdict, self.tolerance)


@dataclass
class Comparison:
    sim: DatasetStats
    real: DatasetStats
    tolerances: Tolerances
    rows: list[Row]
    draws: int  # bootstrap draws behind the rows' intervals
    units: tuple[int, int]  # what the draws resample, sim and real: drives (or frames)


def verdict(sim: float, real: float, tol: float) -> tuple[float | None, str]:
    """(relative difference, verdict); the verdict passes up to and including the tolerance.
    The difference is None where only real is 0 (a fail)."""
    rel = relative_difference(sim, real)
    if math.isnan(rel):
        return rel, "n/a"
    if math.isinf(rel):
        return None, "fail"
    return rel, "pass" if abs(rel) <= tol else "fail"


def compare(sim: DatasetStats, real: DatasetStats, tolerances: Tolerances | None = None,
            draws: int = DRAWS, sim_drives: Mapping[str, str] | None = None,
            real_drives: Mapping[str, str] | None = None) -> Comparison:
    """Every statistic's row; `draws` bootstrap draws give each its interval (0: none), resampling
    drives where `*_drives` ({frame id: drive}, `kitti.read_drives`) say which frames share one."""
    tolerances = tolerances or load_tolerances()
    bounds = intervals(sim, real, draws, sim_drives=sim_drives, real_drives=real_drives)
    rows = []
    for s in STATS:
        a, b = s.value(sim), s.value(real)
        rel, v = verdict(a, b, tolerances.of(s.key))
        rows.append(Row(s.key, s.label, s.unit, a, b, rel, tolerances.of(s.key), v, bounds[s.key]))
    return Comparison(sim, real, tolerances, rows, draws,
                      (len(drive_units(sim.frames, sim_drives)), len(drive_units(real.frames, real_drives))))
