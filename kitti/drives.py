"""Which frames of a KITTI-format root were recorded on the same drive.

Frames of one drive are not independent samples: KITTI's object set holds several frames of many
drives, seconds apart, with the same cars in them, so a bootstrap over frames treats one street as
several (`fidelity.bootstrap` resamples drives instead where it knows them). Two sources:

- a text file, one frame a line: `FRAME_ID DRIVE` (whitespace between; `#` starts a comment);
- the KITTI object devkit's `mapping/` folder: `train_rand.txt` (one line, comma-separated: the
  1-based line of `train_mapping.txt` behind each training frame, in frame order) and
  `train_mapping.txt` (one raw frame a line: `DATE DRIVE RAW_FRAME`).

A frame that neither names is a drive of its own. `drive_units` and `draw_units` are the draws
both bootstraps make of them (`kitti.eval.bootstrap`, `fidelity.bootstrap`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .errors import KittiFormatError

DEVKIT_RAND, DEVKIT_MAPPING = "train_rand.txt", "train_mapping.txt"


def read_drives(path: str | Path) -> dict[str, str]:
    """{frame id (6 digits): drive} from a `FRAME_ID DRIVE` file or the devkit's mapping folder."""
    path = Path(path)
    return _from_devkit(path) if path.is_dir() else _from_pairs(path)


def _from_pairs(path: Path) -> dict[str, str]:
    drives: dict[str, str] = {}
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        tokens = line.split("#", 1)[0].split()
        if not tokens:
            continue
        if len(tokens) != 2:
            raise KittiFormatError(f"expected 'FRAME_ID DRIVE', found {len(tokens)} fields", path, lineno)
        frame, drive = tokens
        if not frame.isdigit():
            raise KittiFormatError(f"'{frame}' is not a frame id", path, lineno, "frame id")
        frame = frame.zfill(6)
        if drives.get(frame, drive) != drive:
            raise KittiFormatError(f"frame {frame} is already on drive '{drives[frame]}'",
                                   path, lineno, "drive")
        drives[frame] = drive
    return drives


def _from_devkit(folder: Path) -> dict[str, str]:
    rand_path, mapping_path = folder / DEVKIT_RAND, folder / DEVKIT_MAPPING
    for p in (rand_path, mapping_path):
        if not p.is_file():
            raise KittiFormatError("no such file (a devkit mapping folder holds train_rand.txt and "
                                   "train_mapping.txt)", p)
    raw = []
    for lineno, line in enumerate(mapping_path.read_text().splitlines(), 1):
        tokens = line.split()
        if len(tokens) != 3:
            raise KittiFormatError(f"expected 'DATE DRIVE RAW_FRAME', found {len(tokens)} fields",
                                   mapping_path, lineno)
        raw.append(tokens[1])
    drives = {}
    entries = [e.strip() for e in rand_path.read_text().replace("\n", ",").split(",") if e.strip()]
    for frame, entry in enumerate(entries):
        if not entry.isdigit() or not 1 <= int(entry) <= len(raw):
            raise KittiFormatError(f"'{entry}' is not a line of {DEVKIT_MAPPING} (1-{len(raw)})",
                                   rand_path, field=f"entry {frame + 1}")
        drives[f"{frame:06d}"] = raw[int(entry) - 1]
    return drives


def drive_units(ids: Sequence[str], drives: Mapping[str, str] | None = None) -> list[np.ndarray]:
    """What a bootstrap draw resamples: the indices into `ids` of each drive's frames (drives in
    the order their first frame comes), every frame that `drives` does not name alone."""
    drives = drives or {}
    members: dict[str, list[int]] = {}
    for i, frame in enumerate(ids):
        members.setdefault(f"drive {drives[frame]}" if frame in drives else f"frame {frame}", []).append(i)
    return [np.array(m) for m in members.values()]


def draw_units(rng: np.random.Generator, units: list[np.ndarray]) -> np.ndarray:
    """One bootstrap draw's frames: as many units as there are, with replacement, each with all its
    frames (the bootstrap of clustered data: Davison & Hinkley, "Bootstrap Methods and their
    Application", 1997). With one frame a unit, in frame order, these are the frames drawn
    directly: the same numbers from the same generator as `rng.integers(n, size=n)`."""
    picked = rng.integers(len(units), size=len(units))
    return picked if all(len(u) == 1 for u in units) else np.concatenate([units[i] for i in picked])


def drawn(ids: Sequence[str], drives: Mapping[str, str] | None = None) -> str:
    """What a bootstrap over `ids` draws, for a printout: "the 11 frames" or "the 11 frames' 8
    drives"."""
    units = len(drive_units(ids, drives))
    return f"the {len(ids)} frames" + ("" if units == len(ids) else f"' {units} drive{'s' * (units != 1)}")
