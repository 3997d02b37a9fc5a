"""A dataset derived from another with a new LiDAR (a rescan, fewer rings) or new labels (a
relabel): links, provenance, and the generator's side files that follow the change.

The derived root is a complete KITTI-format dataset: every file of the source except the folders
the derivation rewrites (velodyne/, velodyne_info/ and meta/ for a new LiDAR; label_2/ and meta/
for new labels) is hard-linked (copied where links are impossible), so everything else stays
byte-identical. A provenance file at the root (`lidar.json`, `labels.json`) records what was
asked; a second run into the same root must ask for the same thing. A generated dataset also
carries the generator's manifest (`simgen.json`) and per-frame meta/: their "lidar" entries (or
their label rules) are rewritten, so neither lies about the files beside it.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

from .io import atomic_write_text
from .velodyne_info import INFO_DIR

PARTS = ("training", "testing")
NEW_DIRS = ("velodyne", INFO_DIR, "meta")  # rewritten per frame by a new LiDAR, never linked
LABEL_DIRS = ("label_2", "meta")  # rewritten per frame by new labels
PROVENANCE = "lidar.json"
LABEL_PROVENANCE = "labels.json"
MANIFEST = "simgen.json"  # the generator's manifest (written by simgen.generate)


def dump_json(record: dict) -> str:
    """Canonical text: sorted keys, so one record always gives the same bytes."""
    return json.dumps(record, sort_keys=True, indent=1) + "\n"


def read_json(path: Path) -> dict:
    try:
        return json.loads(Path(path).read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: line {e.lineno}: not valid JSON: {e.msg}") from None


def meta_with_lidar(meta: dict, counts: dict[int, int], lidar: dict) -> dict:
    """A frame's meta for a new scan: its sensor and each actor's number of returns."""
    meta = dict(meta, lidar=lidar)
    meta["actors"] = [dict(a, lidar_points=int(counts.get(int(a["id"]), 0)))
                      for a in meta.get("actors", [])]
    return meta


def _link_or_copy(src: Path, dst: Path) -> None:
    if dst.exists():
        return
    dst.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(src, dst)
    except OSError:
        tmp = dst.with_name(f".{dst.name}.tmp")
        shutil.copy2(src, tmp)
        os.replace(tmp, dst)


def mirror_dataset(src: Path, dst: Path, new_dirs: tuple[str, ...] = NEW_DIRS) -> None:
    """Link every source file into dst except the folders `new_dirs` of each part."""
    if src.resolve() == dst.resolve():
        raise ValueError(f"--out {dst} is the source dataset itself; choose a new directory")
    for path in sorted(src.rglob("*")):
        rel = path.relative_to(src)
        if not path.is_file() or rel.name in (PROVENANCE, LABEL_PROVENANCE, MANIFEST) \
                or any(part.startswith(".") for part in rel.parts):
            continue  # hidden files are stage markers (.done) or half-written temporaries
        if len(rel.parts) >= 3 and rel.parts[0] in PARTS and rel.parts[1] in new_dirs:
            continue
        _link_or_copy(path, dst / rel)


def claim_output(src: Path, dst: Path, request: dict, provenance: str = PROVENANCE) -> None:
    """Write dst's provenance file, or check that an earlier run there asked for the same thing.

    The source is recorded relative to dst, so the same request gives the same bytes wherever the
    two datasets live (a sweep on another backend or machine writes identical files)."""
    path = dst / provenance
    dst.mkdir(parents=True, exist_ok=True)
    record = {"source": os.path.relpath(src.resolve(), dst.resolve()), **request}
    if path.exists():
        old = json.loads(path.read_text())
        if old != record:
            diff = sorted(k for k in set(old) | set(record) if old.get(k) != record.get(k))
            raise ValueError(f"{path}: {dst} was made by a different request ({', '.join(diff)}); "
                             "use a new --out directory")
        return
    atomic_write_text(path, dump_json(record))
    manifest = src / MANIFEST
    if manifest.exists():
        m = json.loads(manifest.read_text())
        if request["command"] == "rescan":
            m["lidar"] = request["lidar"]
        elif request["command"] == "relabel":
            m["spec"] = {**m["spec"], "labels": request["labels"]}
        elif isinstance(m.get("lidar"), dict):
            m["lidar"] = {**m["lidar"], "beams": request["beams"]}
        atomic_write_text(dst / MANIFEST, dump_json(m))
