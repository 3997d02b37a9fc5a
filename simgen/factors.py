"""Variation factors: a spec value that is fixed, or sampled per frame from a range, a list or steps.

This is the 003 protocol: a study holds one factor at chosen levels and samples the rest. Each
factor is drawn from its own random stream, keyed by (seed, frame, factor name), so fixing one
factor never changes the values drawn for the others.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from pydantic import PlainSerializer, PlainValidator


@dataclass(frozen=True)
class Factor:
    """kind is 'fixed' (values = (v,)), 'range' ((lo, hi), uniform), 'choice' (the list) or
    'steps' ((lo, hi, n): n equally spaced levels from lo to hi, one drawn uniformly)."""

    kind: str
    values: tuple

    def levels(self) -> tuple:
        """Every value the factor can take (range: its two ends)."""
        if self.kind == "steps":
            lo, hi, n = self.values
            return tuple(np.linspace(lo, hi, int(n)).tolist())
        return self.values

    def sample(self, rng: np.random.Generator):
        if self.kind == "fixed":
            return self.values[0]
        if self.kind == "range":
            lo, hi = self.values
            v = float(rng.uniform(lo, hi))
            return int(round(v)) if isinstance(lo, int) and isinstance(hi, int) else v
        levels = self.levels()
        return levels[int(rng.integers(len(levels)))]

    def to_json(self) -> Any:
        if self.kind == "fixed":
            return self.values[0]
        return {self.kind: list(self.values)}


def factor_rng(seed: int, frame: int, name: str) -> np.random.Generator:
    """The independent random stream of one factor in one frame."""
    return np.random.default_rng([int(seed), int(frame), zlib.crc32(name.encode())])


def _check_scalar(v: Any, kind: type, lo: float | None, hi: float | None, options: tuple | None):
    if kind is str:
        if not isinstance(v, str):
            raise ValueError(f"expected a string, got {v!r}")
        if options is not None and v not in options:
            raise ValueError(f"{v!r} is not one of {list(options)}")
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError(f"expected a number, got {v!r}")
    if kind is int and float(v) != int(v):
        raise ValueError(f"expected an integer, got {v!r}")
    v = int(v) if kind is int else float(v)
    if not np.isfinite(v):
        raise ValueError(f"value {v} is not finite")
    if lo is not None and v < lo:
        raise ValueError(f"value {v} is below the minimum {lo}")
    if hi is not None and v > hi:
        raise ValueError(f"value {v} is above the maximum {hi}")
    return v


def _parser(kind: type, lo: float | None, hi: float | None, options: tuple | None):
    def parse(raw: Any) -> Factor:
        if isinstance(raw, Factor):
            return raw
        if not isinstance(raw, dict):
            return Factor("fixed", (_check_scalar(raw, kind, lo, hi, options),))
        if len(raw) != 1:
            raise ValueError(f"a factor is a value or one of {{range|choice|steps: [...]}}, got keys {sorted(raw)}")
        (key, val), = raw.items()
        if key not in ("range", "choice", "steps"):
            raise ValueError(f"unknown factor form {key!r}; use range, choice or steps")
        if not isinstance(val, list) or not val:
            raise ValueError(f"{key} needs a non-empty list")
        if key == "choice":
            return Factor("choice", tuple(_check_scalar(v, kind, lo, hi, options) for v in val))
        if kind is str:
            raise ValueError(f"{key} needs numbers; use choice for names")
        if key == "range":
            if len(val) != 2:
                raise ValueError(f"range needs [lo, hi], got {val!r}")
            a, b = (_check_scalar(v, kind, lo, hi, None) for v in val)
            if a > b:
                raise ValueError(f"range [{a}, {b}] has lo > hi")
            return Factor("range", (a, b))
        if len(val) != 3:
            raise ValueError(f"steps needs [lo, hi, n], got {val!r}")
        a, b = (_check_scalar(v, kind, lo, hi, None) for v in val[:2])
        n = _check_scalar(val[2], int, 1, None, None)
        if a > b or (n == 1 and a != b):
            raise ValueError(f"steps {val!r}: need lo <= hi, and n >= 2 unless lo == hi")
        return Factor("steps", (a, b, n))

    return parse


def factor(kind: type = float, lo: float | None = None, hi: float | None = None,
           options: tuple | None = None):
    """An annotated pydantic type for one factor with bounds (numbers) or options (names)."""
    return Annotated[Factor, PlainValidator(_parser(kind, lo, hi, options)),
                     PlainSerializer(lambda f: f.to_json() if isinstance(f, Factor) else f)]
