"""Reading a folder of label or result files into `{frame id: objects}`."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

from ..errors import KittiFormatError
from ..labels import Object3D, read_label


def load_annotations(label_dir: str | Path, ids: Iterable[str] | None = None,
                     missing_ok: bool = False, progress: bool = False) -> dict[str, list[Object3D]]:
    """Objects of each frame `<label_dir>/<id>.txt`; every `.txt` file when `ids` is None.

    A missing file is an error for truth; for results (`missing_ok=True`) it means no detections.
    """
    label_dir = Path(label_dir)
    if not label_dir.is_dir():
        raise KittiFormatError("not a folder", label_dir)
    ids = sorted(p.stem for p in label_dir.glob("*.txt")) if ids is None else list(ids)
    it = ids
    if progress:
        from tqdm import tqdm
        it = tqdm(ids, desc=f"reading {label_dir.name}", unit="frame", leave=False, delay=0.5,
                  disable=None)  # as kitti.eval.evaluate's bars: on a terminal, for a slow read
    out = {}
    for fid in it:
        path = label_dir / f"{fid}.txt"
        if not path.is_file():
            if missing_ok:
                out[fid] = []
                continue
            raise KittiFormatError(f"frame {fid} has no label file", path)
        out[fid] = read_label(path)
    return out
