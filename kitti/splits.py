"""ImageSets/{train,val,test,trainval}.txt: one 6-digit frame id per line."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

from .errors import KittiFormatError
from .io import atomic_write_text


def read_split(path: str | Path) -> list[str]:
    path = Path(path)
    ids = []
    for lineno, line in enumerate(path.read_text().splitlines(), 1):
        tok = line.strip()
        if not tok:
            continue
        if not tok.isdigit():
            raise KittiFormatError(f"'{tok}' is not a frame id", path, lineno, "frame id")
        ids.append(tok.zfill(6))
    return ids


def write_split(path: str | Path, ids: Iterable[str]) -> None:
    atomic_write_text(path, "".join(f"{str(i).zfill(6)}\n" for i in ids))
