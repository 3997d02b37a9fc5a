"""What a generated scan's returns hit, in SemanticKITTI's classes, beside the share of points
each class holds over SemanticKITTI's whole labelled set (a reference for the world's make-up
that does not come from the eleven dev frames), and the mean reflectance each class's returns
read (SemanticKITTI publishes no per-class reading: a diagnosis of what moves the scan's mean).

    .venv/bin/python benchmarks/return_classes.py [--spec scenes/urban.yaml] [--frames 24] [--seed 0]

SemanticKITTI (Behley et al., ICCV 2019) labelled every point of the KITTI odometry sequences
00-10: 23,201 scans of the same HDL-64E on the same car, driven through Karlsruhe's residential
streets, its city centre, country roads and one highway (sequence 01). Its devkit
(`semantic-kitti-api`, `config/semantic-kitti.yaml`, `content`) gives each class's share of all
those points; `SEMANTIC_KITTI` below holds them, with "moving" classes folded into their static
ones and lane marking into road, as the benchmark's own learning map does. The KITTI object
frames were drawn from the same recordings, weighted to frames with objects in view (more city,
fewer country roads), so the shares are a reference for the kind of streets, not a target to fit.

The last line splits the vehicle returns by whether the vehicle moves (`simgen.world.Actor.moving`)
against SemanticKITTI's own standing and "moving-" classes.

Returns on an actor are counted by its class (`simgen.world.Actor.cls`); every other return by
the material of the surface its ray meets (`materials_hit` below, which names a return
behind a facade's glass "window"). Kerbs and the low walls of plot boundaries share one concrete
material: a return on it standing more than WALL_ABOVE over the kerb's top (the road's surface
under it plus the curb height) is a wall's and counts as fence, the rest as sidewalk (kerbs).
(SemanticKITTI's class definitions were not at hand to say whether its annotators put such walls
in fence or in other-structure, which is folded into "other" here.)
"""

from __future__ import annotations

import kitti  # noqa: F401  (first: pins the CPU kernels before numpy or torch loads)

import argparse
import collections

import numpy as np
from tqdm import tqdm

from simgen import lidar
from simgen.road import RoadLayout
from simgen.sample import sample_world
from simgen.spec import load_spec

# Share of all points, SemanticKITTI sequences 00-10 (config/semantic-kitti.yaml, `content`,
# moving classes folded in). The rest (0.0315) is unlabeled, outlier, other structure and other
# object.
SEMANTIC_KITTI = {
    "road": 0.1988 + 0.0147,  # road, lane marking; parking (an area beside the road, same surface)
    "sidewalk": 0.1439,
    "other-ground": 0.0039,
    "building": 0.1327,
    "fence": 0.0724,
    "vegetation": 0.2668,
    "trunk": 0.0060,
    "terrain": 0.0781,
    "pole": 0.0029,
    "traffic-sign": 0.0006,
    "car": 0.0426,
    "truck": 0.0022,
    "other-vehicle": 0.0018 + 0.0004,  # other vehicle, motorcycle and motorcyclist
    "person": 0.0003,
    "bicycle, cyclist": 0.0003,
}
OTHER = "other (unlabeled, other structure or object)"
# The same devkit's vehicle classes split into standing and moving (car, truck, other vehicle, bus,
# motorcycle; each's "moving-" class, motorcyclists with their motorcycles): a vehicle return
# over the whole labelled set is a standing vehicle's 95.6 % of the time (4.493 % of all points
# against 0.209 %). Standing is what SemanticKITTI's annotators saw not move: parked cars and
# cars waiting in a queue alike.
VEHICLES_STANDING = 0.040819 + 0.002063 + 0.001622 + 0.0000279 + 0.000398
VEHICLES_MOVING = 0.001789 + 0.000102 + 0.0000438 + 0.000114 + 0.0000375

BY_ACTOR = {"Car": "car", "Van": "car", "Truck": "truck", "Bus": "other-vehicle",
            "Tram": "other-vehicle", "Misc": OTHER, "Pedestrian": "person",
            "Cyclist": "bicycle, cyclist"}
VEHICLES = ("car", "truck", "other-vehicle")
BY_MATERIAL = {
    "asphalt": "road", "marking": "road",
    "sidewalk": "sidewalk", "curb": "sidewalk",  # kerbs (low concrete walls: fence, classes_of)
    "facade": "building", "window": "building",
    "fence": "fence",
    "foliage": "vegetation",
    "bark": "trunk",
    "verge": "terrain", "forest_floor": "terrain", "sand": "terrain",
    "pole": "pole",
    "sign_white": "traffic-sign", "sign_yellow": "traffic-sign", "sign_red": "traffic-sign",
    "sign_blue": "traffic-sign",
    "bike_frame": "bicycle, cyclist",  # the cycle stands' parked bicycles
}


def materials_hit(world, spec: lidar.LidarSpec, scan: lidar.LidarScan, tgt: lidar.Target) -> np.ndarray:
    """Material name of the surface behind each return, 'none' where no triangle; 'window' where
    the ray meets a façade that can hold windows and the return lies more than 10 cm beyond it (a
    curtain or a room behind the glass: simgen.lidar.windows). Each return's ray is cast again
    from the sensor's origin at its firing time into the scan's own scene (`tgt`); the lasers'
    few-centimetre offsets from that origin are ignored."""
    poses = world.lidar_pose_at(scan.time.astype(np.float64))  # the sensor at each firing
    origin = poses[:, :3, 3]
    d = np.einsum("nij,nj->ni", poses[:, :3, :3], scan.points[:, :3].astype(np.float64))
    r = np.linalg.norm(d, axis=1)
    d /= r[:, None]
    res = tgt.scene.run(origin.astype(np.float32), d.astype(np.float32), output=1)
    prim = res["primID"]
    names = np.array([m.name for m in tgt.materials] + ["none", "window"])
    index = np.where(prim >= 0, tgt.tri_mat[np.maximum(prim, 0)], len(tgt.materials))
    behind = (prim >= 0) & (tgt.windows.tri_wall[np.maximum(prim, 0)] >= 0) & (r > res["tfar"] + 0.1)
    index[behind] = len(tgt.materials) + 1
    return names[index]


WALL_ABOVE = 0.05  # m over the kerb's top: kerb faces end there, walls stand 0.5-1.2 m above it


def classes_of(world, scan: lidar.LidarScan, sensor: lidar.LidarSpec, target) -> np.ndarray:
    """SemanticKITTI class name per return (`target`: the scan's own Embree scene)."""
    cls = {a.id: BY_ACTOR.get(a.cls, OTHER) for a in world.actors}
    names = materials_hit(world, sensor, scan, target)
    out = np.array([BY_MATERIAL.get(n, OTHER) for n in names.tolist()], dtype=object)
    concrete = np.flatnonzero(names == "curb")
    if len(concrete):  # the return in the world frame, against the kerb's top under it
        road = RoadLayout(**world.scenery["road"])
        poses = world.lidar_pose_at(scan.time[concrete].astype(np.float64))
        p = poses[:, :3, 3] + np.einsum("nij,nj->ni", poses[:, :3, :3],
                                        scan.points[concrete, :3].astype(np.float64))
        wall = p[:, 2] > road.height(p[:, 0], p[:, 1]) + road.curb_height + WALL_ABOVE
        out[concrete[wall]] = "fence"
    on_actor = scan.actor_id > 0
    out[on_actor] = [cls[int(i)] for i in scan.actor_id[on_actor]]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="scenes/urban.yaml")
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    spec = load_spec(args.spec)
    sensor = lidar.preset(spec.lidar.preset, beams=spec.lidar.beams, max_range=spec.lidar.max_range)
    counts, reading, n = collections.Counter(), collections.Counter(), 0
    vehicle_returns = collections.Counter()  # on vehicles standing / moving (Actor.moving)
    for i in tqdm(range(args.frames), desc="frames"):
        world = sample_world(spec, args.seed, i)
        target = lidar.build_target(world, sensor)
        swept = lidar.scan(world, sensor, 0, target)
        classes = classes_of(world, swept, sensor, target)
        counts.update(classes.tolist())
        for name in set(classes.tolist()):  # the reflectance each class's returns read, summed
            reading[name] += float(swept.points[classes == name, 3].sum())
        n += len(swept.points)
        vehicles = [a for a in world.actors if BY_ACTOR.get(a.cls) in VEHICLES]
        for state in ("moving", "standing"):
            ids = [a.id for a in vehicles if a.moving == (state == "moving")]
            vehicle_returns[state] += int(np.isin(swept.actor_id, ids).sum())
    print(f"{args.spec}, {args.frames} frames (seed {args.seed}), {n / args.frames:,.0f} returns a frame")
    print("| class | generated (%) | SemanticKITTI, sequences 00-10 (%) | ratio | generated: mean reflectance |"
          "\n|---|---:|---:|---:|---:|")
    mean = (lambda name: reading[name] / counts[name] if counts[name] else float("nan"))
    for name, ref in sorted(SEMANTIC_KITTI.items(), key=lambda kv: -kv[1]):
        share = counts[name] / n
        print(f"| {name} | {100 * share:.2f} | {100 * ref:.2f} | {share / ref:.2f} | {mean(name):.3f} |")
    rest = 1.0 - sum(SEMANTIC_KITTI.values())
    print(f"| {OTHER} | {100 * counts[OTHER] / n:.2f} | {100 * rest:.2f} | {counts[OTHER] / n / rest:.2f} "
          f"| {mean(OTHER):.3f} |")
    print(f"every return: mean reflectance {sum(reading.values()) / n:.3f}")
    grouped = {"ground (road, sidewalk, other ground, terrain)":
               ("road", "sidewalk", "other-ground", "terrain"),
               "vegetation and trunks": ("vegetation", "trunk"),
               "vehicles": VEHICLES}
    for label, keys in grouped.items():
        print(f"{label}: generated {100 * sum(counts[k] for k in keys) / n:.1f} %, "
              f"SemanticKITTI {100 * sum(SEMANTIC_KITTI[k] for k in keys):.1f} %")
    on_vehicles = sum(vehicle_returns.values())
    print(f"vehicle returns on moving vehicles: generated "
          f"{100 * vehicle_returns['moving'] / max(on_vehicles, 1):.1f} %, SemanticKITTI "
          f"{100 * VEHICLES_MOVING / (VEHICLES_MOVING + VEHICLES_STANDING):.1f} %; on standing ones "
          f"{100 * vehicle_returns['standing'] / n:.2f} % of all returns (SemanticKITTI "
          f"{100 * VEHICLES_STANDING:.2f} %), on moving ones {100 * vehicle_returns['moving'] / n:.2f} % "
          f"({100 * VEHICLES_MOVING:.2f} %)")


if __name__ == "__main__":
    main()
