"""Sim against real, statistic by statistic: the relative difference (sim - real) / |real| and a
pass/fail verdict against a per-statistic tolerance from tolerances.yaml."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

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


@dataclass
class Comparison:
    sim: DatasetStats
    real: DatasetStats
    tolerances: Tolerances
    rows: list[Row]


def verdict(sim: float, real: float, tol: float) -> tuple[float | None, str]:
    """(relative difference, verdict); the verdict passes up to and including the tolerance."""
    if math.isnan(sim) or math.isnan(real):
        return float("nan"), "n/a"
    if real == 0:
        return (0.0, "pass") if sim == 0 else (None, "fail")
    rel = (sim - real) / abs(real)
    return rel, "pass" if abs(rel) <= tol else "fail"


def compare(sim: DatasetStats, real: DatasetStats, tolerances: Tolerances | None = None) -> Comparison:
    tolerances = tolerances or load_tolerances()
    rows = []
    for s in STATS:
        a, b = s.value(sim), s.value(real)
        rel, v = verdict(a, b, tolerances.of(s.key))
        rows.append(Row(s.key, s.label, s.unit, a, b, rel, tolerances.of(s.key), v))
    return Comparison(sim, real, tolerances, rows)
