"""Atomic writes: a reader never sees a half-written file, a crash never leaves one."""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside `path`; rename it onto `path` only if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o644)
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def release_pages(paths: Iterable[str | Path]) -> None:
    """Tell the kernel that `paths` will not be read again soon (POSIX_FADV_DONTNEED): their
    dirty pages start going to disk and their clean pages leave the page cache; a missing file
    is skipped. Nothing happens where the OS has no posix_fadvise. Bulk writers call it on what
    they wrote so that the cache's pages are reused instead of new memory taken for each file:
    on a virtual machine whose memory the host backs lazily, a new page costs a fault on the
    host (2 MB written into reused pages 0.5 ms, into new ones 3 to 30 ms)."""
    if not hasattr(os, "posix_fadvise"):
        return
    for path in paths:
        try:
            fd = os.open(path, os.O_RDONLY)
        except FileNotFoundError:
            continue
        try:
            os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
        finally:
            os.close(fd)


class WriteBehind:
    """Releases a bulk writer's files from the page cache one batch after writing them.

    A generated dataset is written once and read later, often by another process or thousands of
    frames on, so its pages in the cache are worth little while each new one costs memory the
    kernel must find (`release_pages`). Each batch (a frame's files) is handed over once written:
    its write-back starts at once, and at the next batch, long written back, its pages are let go
    (pages still dirty or under write-back cannot be). One per process."""

    def __init__(self) -> None:
        self._previous: list[Path] = []

    def written(self, paths: list[Path]) -> None:
        """Start `paths`' write-back; release the batch before."""
        release_pages(self._previous + paths)
        self._previous = paths
