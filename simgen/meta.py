"""meta/NNNNNN.json: everything needed to rebuild a frame's world exactly, plus per-actor truth.

Floats go through JSON as Python's shortest round-trip repr, so poses, sizes and scenery
parameters come back bit for bit; meshes are rebuilt from their recipes (procedural parameters
and seed, or a user mesh's path), the static world from its scenery parameters.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from kitti.calib import KEYS, Calibration
from kitti.derived import read_json

from .labels import ActorTruth
from .meshes import build_actor_parts
from .rigs import CameraRig
from .scenery import build_scenery
from .world import Actor, Light, Weather, World

FORMAT = "simgen-meta/1"


def _rig_to_json(rig: CameraRig) -> dict:
    return {"kind": rig.kind, "width": rig.width, "height": rig.height,
            "reference_pose": rig.reference_pose.tolist(), "params": rig.params,
            "calib": {k: getattr(rig.calib, k).tolist() for k in KEYS}}


def _rig_from_json(d: dict) -> CameraRig:
    calib = Calibration(**{k: np.array(d["calib"][k]) for k in KEYS})
    return CameraRig(d["kind"], calib, d["width"], d["height"], np.array(d["reference_pose"]),
                     d["params"])


def _truth_fields(t: ActorTruth) -> dict:
    return {"box7": t.box7.tolist(), "in_view": t.in_view,
            "bbox": None if t.bbox is None else t.bbox.tolist(),
            "silhouette_bbox": None if t.silhouette_bbox is None else t.silhouette_bbox.tolist(),
            "truncation": t.truncation, "visible_px": t.visible_px,
            "visible_share": t.visible_share, "occluded": t.occluded,
            "distance": t.distance, "label": t.label}


def meta_with_truths(meta: dict, truths: list[ActorTruth], labels: dict) -> dict:
    """A frame's meta relabelled: the label rules `labels` (as spec_to_dict writes them) in its
    spec and the labeller's new per-actor truth; the world and the sensor as they were."""
    by_id = {t.id: t for t in truths}
    actors = [dict(a, **_truth_fields(by_id[a["id"]])) if a["id"] in by_id else dict(a)
              for a in meta["actors"]]
    return dict(meta, spec=dict(meta["spec"], labels=labels), actors=actors)


def world_to_meta(world: World, spec: dict | None = None, truths: list[ActorTruth] | None = None,
                  lidar_counts: dict[int, int] | None = None, lidar: dict | None = None) -> dict:
    """A JSON-able dict of the world, its spec and (when given) the labeller's per-actor truth."""
    by_id = {t.id: t for t in truths or []}
    actors = []
    for a in world.actors:
        row = {"id": a.id, "class": a.cls, "mesh": a.recipe, "pose": a.pose.tolist(),
               "velocity": np.asarray(a.velocity, float).tolist(), "yaw_rate": a.yaw_rate}
        if a.stop_lamps:  # only where lit: worlds without braking keep their meta
            row["stop_lamps"] = True
        t = by_id.get(a.id)
        if t is not None:
            row.update(_truth_fields(t))
        if lidar_counts is not None:
            row["lidar_points"] = int(lidar_counts.get(a.id, 0))
        actors.append(row)
    return {"format": FORMAT, "seed": world.seed, "frame_index": world.frame_index, "spec": spec,
            "rig": _rig_to_json(world.rig), "light": asdict(world.light),
            "weather": asdict(world.weather), "sensor": world.sensor,
            "lidar_pose": world.lidar_pose.tolist(),
            "ego_velocity": np.asarray(world.ego_velocity, float).tolist(), "lidar": lidar,
            "scenery": world.scenery, "actors": actors}


def world_from_meta(meta: dict) -> World:
    """The exact world a meta dict (or meta/NNNNNN.json, loaded) was written from."""
    if meta.get("format") != FORMAT:
        raise ValueError(f"not a {FORMAT} file (format: {meta.get('format')!r})")
    static, _ = build_scenery(meta["scenery"])
    actors = [Actor(a["id"], a["class"], build_actor_parts(a["mesh"]), np.array(a["pose"]),
                    velocity=np.array(a["velocity"]), yaw_rate=a["yaw_rate"], recipe=a["mesh"],
                    stop_lamps=bool(a.get("stop_lamps", False)))
              for a in meta["actors"]]
    return World(actors=actors, static=static, weather=Weather(**meta["weather"]),
                 lidar_pose=np.array(meta["lidar_pose"]), ego_velocity=np.array(meta["ego_velocity"]),
                 rig=_rig_from_json(meta["rig"]), light=Light(**meta["light"]),
                 sensor=meta["sensor"], scenery=meta["scenery"], seed=meta["seed"],
                 frame_index=meta["frame_index"])


def meta_ids(root: Path, command: str, part: str = "training") -> list[str]:
    """The frame ids of a generated root's meta/, which `command` rebuilds worlds from."""
    meta_dir = Path(root) / part / "meta"
    ids = sorted(p.stem for p in meta_dir.glob("*.json"))
    if not ids:
        raise ValueError(f"{meta_dir}: no meta/NNNNNN.json to rebuild worlds from "
                         f"({command} needs a dataset written by `testbed generate`)")
    return ids


def load_world(meta_path: Path) -> tuple[dict, World]:
    """A frame's meta/NNNNNN.json and the world rebuilt from it; one that cannot rebuild a world
    is named."""
    meta = read_json(meta_path)
    try:
        return meta, world_from_meta(meta)
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError(f"{meta_path}: cannot rebuild the world: {e}") from None
