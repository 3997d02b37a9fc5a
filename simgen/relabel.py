"""The same frames, other label rules: rebuild every frame's world from its meta and label it again.

A relabel is a derived dataset (`kitti.derived`): images, scans, calib, planes and the depth and
instance side data are linked and stay byte-identical; label_2/ and meta/ are new. Each frame
goes through the generator's own labeller (`simgen.labels.derive`) with the rebuilt world, the
frame's instance image and, for rules that count them, the LiDAR returns per actor that its meta
records, so relabelling with the rules a dataset was generated with reproduces its labels and
meta byte for byte, and relabelling with other rules gives what `testbed generate` with those
rules writes, without rendering or scanning anything. A label rule study (which objects KITTI
would have labelled, which left as DontCare) costs seconds a hundred frames instead of a
regeneration. A frame is done once its label and meta exist, so a stopped relabel resumes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
from pydantic import ValidationError

from kitti.derived import (LABEL_DIRS, LABEL_PROVENANCE, MANIFEST, claim_output, dump_json,
                           mirror_dataset, read_json)
from kitti.io import atomic_write_text
from kitti.jobs import Backend, InProcess
from kitti.labels import write_label

from .spec import LabelRules


@dataclass(frozen=True)
class RelabelJob:
    src: Path  # source part folder (…/training)
    dst: Path
    fid: str
    rules: LabelRules


def source_rules(src: Path) -> LabelRules:
    """The label rules a generated dataset was written with (its manifest, `simgen.json`)."""
    path = src / MANIFEST
    if not path.exists():
        raise ValueError(f"{path}: no generator manifest (relabel needs a dataset written by "
                         "`testbed generate`)")
    labels = read_json(path).get("spec", {}).get("labels")
    if not isinstance(labels, dict):
        raise ValueError(f"{path}: key 'spec.labels' missing: not a `testbed generate` manifest")
    try:
        return LabelRules.model_validate(labels)
    except ValidationError as e:  # named by the manifest's key, not taken for an option's error
        raise ValueError(f"{path}: key 'spec.labels': {e.errors()[0]['msg']}") from None


def relabel_frame(job: RelabelJob) -> str:
    """Rebuild one frame's world from its meta and write its label and meta under the rules."""
    from .labels import derive
    from .meta import load_world, meta_with_truths

    label_out = job.dst / "label_2" / f"{job.fid}.txt"
    meta_out = job.dst / "meta" / f"{job.fid}.json"
    if label_out.exists() and meta_out.exists():
        return job.fid
    meta_path = job.src / "meta" / f"{job.fid}.json"
    meta, world = load_world(meta_path)
    inst_path = job.src / "instance_2" / f"{job.fid}.png"
    instance = cv2.imread(str(inst_path), cv2.IMREAD_UNCHANGED)
    if instance is None or instance.shape != (world.rig.height, world.rig.width):
        raise ValueError(f"{inst_path}: missing or not the frame's {world.rig.width}x"
                         f"{world.rig.height} 16-bit instance image")
    counts = None
    if meta.get("lidar") is not None:
        counts = {int(a["id"]): int(a["lidar_points"]) for a in meta["actors"] if "lidar_points" in a}
    elif job.rules.min_lidar_points:
        raise ValueError(f"{meta_path}: the frame has no scan; labels.min_lidar_points needs one")
    objects, truths = derive(world, instance, job.rules, counts)
    write_label(label_out, objects)
    atomic_write_text(meta_out, dump_json(meta_with_truths(meta, truths,
                                                           job.rules.model_dump(mode="json"))))
    return job.fid


def relabel_jobs(src: Path, out: Path, rules: LabelRules) -> list[RelabelJob]:
    """Check the source, claim and mirror the output root, and list one job per frame."""
    from .meta import meta_ids

    ids = meta_ids(src, "relabel")
    source_rules(src)  # a generated dataset, with a manifest to rewrite
    claim_output(src, out, {"command": "relabel", "labels": rules.model_dump(mode="json")},
                 provenance=LABEL_PROVENANCE)
    mirror_dataset(src, out, new_dirs=LABEL_DIRS)
    return [RelabelJob(src / "training", out / "training", fid, rules) for fid in ids]


def relabel(src: Path, out: Path, rules: LabelRules, backend: Backend | None = None) -> list[str]:
    """Write `out`: the frames of `src` labelled under `rules`; the frame ids."""
    jobs = relabel_jobs(src, out, rules)
    return (backend or InProcess()).map(relabel_frame, jobs, desc="relabel")
