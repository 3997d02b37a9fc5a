"""One error type for every malformed KITTI input, naming where it went wrong."""

from __future__ import annotations

from pathlib import Path


class KittiFormatError(ValueError):
    """Malformed KITTI data. The message names the file, the line and the field."""

    def __init__(self, msg: str, path: str | Path | None = None, line: int | None = None,
                 field: str | None = None):
        self.path = None if path is None else str(path)
        self.line = line
        self.field = field
        where = []
        if self.path is not None:
            where.append(self.path)
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field '{field}'")
        super().__init__(f"{': '.join([', '.join(where), msg]) if where else msg}")
