"""label_2 lines: `type truncated occluded alpha x1 y1 x2 y2 h w l x y z rotation_y [score]`.

Precision on write: 4 decimals (0.1 mm, 1e-4 rad, 1e-4 px) for geometry, 2 for truncation,
so reading a written file gives back the written values exactly and writing them again gives the
same bytes. Dimension -1 and location -1000 are the format's placeholders for "unknown" (DontCare
rows, 2D-only result files); any other negative dimension is an error.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

import numpy as np

from .errors import KittiFormatError
from .io import atomic_write_text

FIELDS = ("type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2",
          "h", "w", "l", "x", "y", "z", "rotation_y", "score")


@dataclass
class Object3D:
    """One labelled (or detected) object of a KITTI frame."""

    type: str
    truncated: float
    occluded: int
    alpha: float
    bbox: np.ndarray  # (4,) x1, y1, x2, y2 in image_2 pixels
    h: float
    w: float
    l: float
    location: np.ndarray  # (3,) bottom-face centre, rectified camera-0 frame
    rotation_y: float
    score: float | None = field(default=None)

    def __post_init__(self) -> None:
        self.bbox = np.asarray(self.bbox, dtype=float).reshape(4)
        self.location = np.asarray(self.location, dtype=float).reshape(3)

    @property
    def box7(self) -> np.ndarray:
        """[x, y, z, h, w, l, ry]: the box layout every geometry function takes."""
        return np.array([*self.location, self.h, self.w, self.l, self.rotation_y], dtype=float)

    @property
    def height_px(self) -> float:
        return float(self.bbox[3] - self.bbox[1])

    @classmethod
    def dont_care(cls, bbox) -> "Object3D":
        return cls("DontCare", -1.0, -1, -10.0, bbox, -1.0, -1.0, -1.0,
                   np.array([-1000.0, -1000.0, -1000.0]), -10.0)

    def to_line(self) -> str:
        x1, y1, x2, y2 = self.bbox
        x, y, z = self.location
        parts = [self.type, f"{self.truncated:.2f}", f"{int(self.occluded)}", f"{self.alpha:.4f}",
                 f"{x1:.4f}", f"{y1:.4f}", f"{x2:.4f}", f"{y2:.4f}",
                 f"{self.h:.4f}", f"{self.w:.4f}", f"{self.l:.4f}",
                 f"{x:.4f}", f"{y:.4f}", f"{z:.4f}", f"{self.rotation_y:.4f}"]
        if self.score is not None:
            parts.append(f"{self.score:.6f}")
        return " ".join(_unsigned_zero(p) for p in parts)


def _unsigned_zero(tok: str) -> str:
    """A value that rounds to zero is written without a sign ("-0.0000" -> "0.0000"); every other
    negative value keeps its sign, however small."""
    return tok[1:] if tok.startswith("-") and float(tok) == 0.0 else tok


def _float(tok: str, name: str, path, lineno) -> float:
    try:
        v = float(tok)
    except ValueError:
        raise KittiFormatError(f"'{tok}' is not a number", path, lineno, name) from None
    if not np.isfinite(v):
        raise KittiFormatError(f"'{tok}' is not a finite number", path, lineno, name)
    return v


def parse_label_line(line: str, path: str | Path = "<string>", lineno: int = 1) -> Object3D:
    toks = line.split()
    if len(toks) not in (15, 16):
        raise KittiFormatError(f"expected 15 or 16 fields, found {len(toks)}", path, lineno,
                               "field count")
    vals = {name: _float(tok, name, path, lineno) for name, tok in zip(FIELDS[1:], toks[1:])}
    occ = vals["occluded"]
    if occ != int(occ):
        raise KittiFormatError(f"'{toks[2]}' is not an integer", path, lineno, "occluded")
    for name in ("h", "w", "l"):
        if vals[name] < 0 and vals[name] != -1.0:
            raise KittiFormatError(f"negative dimension {vals[name]}", path, lineno, name)
    return Object3D(
        type=toks[0], truncated=vals["truncated"], occluded=int(occ), alpha=vals["alpha"],
        bbox=np.array([vals["x1"], vals["y1"], vals["x2"], vals["y2"]]),
        h=vals["h"], w=vals["w"], l=vals["l"],
        location=np.array([vals["x"], vals["y"], vals["z"]]), rotation_y=vals["rotation_y"],
        score=vals.get("score"))


def read_label(path: str | Path) -> list[Object3D]:
    path = Path(path)
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise KittiFormatError("not a text file", path) from None
    return [parse_label_line(line, path, i) for i, line in enumerate(text.splitlines(), 1)
            if line.strip()]


def format_label(objects: Iterable[Object3D]) -> str:
    return "".join(o.to_line() + "\n" for o in objects)


def write_label(path: str | Path, objects: Iterable[Object3D]) -> None:
    atomic_write_text(path, format_label(objects))


def boxes7(objects: Iterable[Object3D]) -> np.ndarray:
    """(N, 7) [x, y, z, h, w, l, ry] for a list of objects."""
    rows = [o.box7 for o in objects]
    return np.array(rows, dtype=float).reshape(-1, 7)
