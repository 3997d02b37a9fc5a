"""planes/NNNNNN.txt: the road plane a·x + b·y + c·z + d = 0 in rectified camera coordinates.

The file is KITTI's: a '# Plane' line, 'Width 4', 'Height 1', then the four coefficients.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import KittiFormatError
from .io import atomic_write_text


def read_plane(path: str | Path) -> np.ndarray:
    path = Path(path)
    lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
    if not lines:
        raise KittiFormatError("empty plane file", path)
    lineno = len(lines)
    toks = lines[-1].split()
    if len(toks) != 4:
        raise KittiFormatError(f"expected 4 coefficients, found {len(toks)}", path, lineno, "plane")
    try:
        return np.array([float(t) for t in toks])
    except ValueError:
        raise KittiFormatError("coefficient is not a number", path, lineno, "plane") from None


def write_plane(path: str | Path, plane) -> None:
    a, b, c, d = (float(v) for v in np.asarray(plane).reshape(4))
    atomic_write_text(path, f"# Plane\nWidth 4\nHeight 1\n{a:.6e} {b:.6e} {c:.6e} {d:.6e}\n")
