"""Sample a world from a spec, a seed and a frame index: deterministic, collision-free.

Actors stand on the road or the sidewalk (curb height above it; on a road with a vertical
profile, both rise and fall with it: `simgen.relief`), face along their lane with a
small spread, and never overlap each other, the ego vehicle or static obstacles (footprints
tested as oriented rectangles with a safety margin; tree crowns only against actors tall enough
to reach them). Parked rows line the kerbs that have a parking strip, bays nose to tail, and
a queue of standing vehicles may wait in the lane beside the ego's (`_Traffic.parked`,
`_Traffic.queue`). With `clutter.frontage`, cars also stand in car-park stalls (paved at curb
height, across the road), and side streets keep their mouths free of parked cars and walkers.
"""

from __future__ import annotations

import functools

import numpy as np
import shapely

from .factors import factor_rng
from .meshes import build_actor_parts, sample_recipe
from .relief import drape_actor
from .rigs import KITTI_LIDAR_HEIGHT, CameraRig, gantry_rig, onboard_rig, orbit_rig
from .road import RoadLayout, VerticalProfile
from .scenery import Frontage, Obstacle, build_scenery, plan_frontage
from .spec import VEHICLE_CLASSES, SceneSpec
from .usermesh import user_recipe
from .world import Actor, Appearance, CameraResponse, Light, Weather, World

MARGIN = 0.3  # metres of free space kept around every actor footprint
VERGE_REACH = 60.0  # cross-street traffic runs from -60 to 60 m across the main road
# Parked vehicles (curbs and car parks): one Van to ten Cars, as in KITTI's training labels (2,914
# Vans, 28,742 Cars; the sizes of each class come from the same labels: simgen.meshes.SIZE_STATS).
PARKED_MIX = {"Car": 0.908, "Van": 0.092}
# Parked rows (_Traffic.parked). Gaps between parked vehicles: about 1 m front and back usually
# suffices, courts accepted 0.8 m in front and 0.5 m behind (commentary on StVO section 12, Bouska);
# 0.8 m is the gap the Berlin OSM kerb-parking survey assumes. No parking within 5 m of the
# crossing of the carriageways' edges at junctions (StVO section 12(3) no. 1). Distance from the
# kerb: StVO section 12(4) asks for the carriageway's right edge and names none; 0.05-0.30 m is a
# judgement. Parked vehicles keep 0.2 m of free space around their footprints, so gaps of 0.5 m fit.
PARKED_GAP = (0.5, 1.0)
CORNER_CLEAR = 5.0
KERB_GAP = (0.05, 0.30)
PARKED_MARGIN = 0.2
# Standing queues (_Traffic.queue, _Traffic._column): the standstill gap of car following, 2 m in
# the Intelligent Driver Model (Treiber, Hennecke and Helbing, Phys. Rev. E 62, 2000), drawn 1-3 m.
# Where a queue beside the ego begins (20 m behind the LiDAR to 5 m ahead) and how far a queue
# reaches (15-60 m): a judgement.
QUEUE_GAP = (1.0, 3.0)
QUEUE_START = (-20.0, 5.0)
QUEUE_LENGTH = (15.0, 60.0)
# KITTI's VW Passat around its LiDAR (x -2.9 to 1.3 m), plus 5 m of free lane ahead of its bumper.
EGO_FREE_AHEAD = 6.3  # where that free lane ends, m ahead of the LiDAR
EGO_FOOTPRINT = shapely.box(-2.9, -1.0, EGO_FREE_AHEAD, 1.0)


def _values(spec: SceneSpec, seed: int, frame: int) -> dict:
    """Every factor of the spec drawn for this frame, each from its own stream."""
    out = {}
    for section in ("road", "traffic", "clutter", "rig", "light", "weather", "appearance", "camera"):
        model = getattr(spec, section)
        for name in type(model).model_fields:
            v = getattr(model, name)
            key = f"{section}.{name}"
            out[key] = v.sample(factor_rng(seed, frame, key)) if hasattr(v, "sample") else v
    out["sensor"] = spec.sensor.sample(factor_rng(seed, frame, "sensor"))
    return out


def _plain(value):
    """A drawn factor value as a plain Python bool or float."""
    return value if isinstance(value, bool) else float(value)


def _footprint(pose: np.ndarray, l: float, w: float, margin: float = MARGIN) -> shapely.Polygon:
    """The pose's l x w rectangle grown by `margin` each side, in plan view."""
    hl, hw = l / 2 + margin, w / 2 + margin
    c = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    return shapely.polygons(c @ pose[:2, :2].T + pose[:2, 3])


class _Placer:
    """Keeps the footprints placed so far and accepts only non-overlapping new ones. The static
    obstacles are queried through an STRtree (the same intersects predicate, tested only where
    the envelopes meet), the few placed footprints in one vectorised GEOS call."""

    def __init__(self, obstacles: list[Obstacle], reserved: list[shapely.Polygon]):
        self.tree = shapely.STRtree([o.polygon for o in obstacles])
        self.bases = np.array([o.base for o in obstacles], float)
        self.taken = list(reserved)

    def try_place(self, pose: np.ndarray, recipe: dict, margin: float = MARGIN) -> bool:
        h, w, l = recipe["dims"]
        fp = _footprint(pose, l, w, margin)
        shapely.prepare(fp)
        if self.taken and shapely.intersects(fp, self.taken).any():
            return False
        hits = self.tree.query(fp, predicate="intersects")
        if (self.bases[hits] < pose[2, 3] + h).any():
            return False
        self.taken.append(fp)
        return True


def _recipe(cls: str, spec: SceneSpec, rng: np.random.Generator) -> dict:
    users = [u for u in spec.user_meshes if u.cls == cls]
    for u in users:
        if rng.uniform() < u.share:
            return user_recipe(u.path, cls, u.size, u.up, u.color, u.reflectivity)
    if cls in ("Misc",):
        raise ValueError("class Misc needs a user mesh")
    return sample_recipe(cls, rng)


def _pick_class(mix: dict[str, float], rng: np.random.Generator) -> str:
    names, p = _odds(tuple(sorted(mix.items())))
    return names[int(rng.choice(len(names), p=p))]


@functools.lru_cache(maxsize=64)
def _odds(mix: tuple[tuple[str, float], ...]) -> tuple[tuple[str, ...], np.ndarray]:
    """A class mix's names in order and their probabilities, made once per mix (per draw they
    cost more than the draw)."""
    p = np.array([w for _, w in mix], dtype=float)
    p = p / p.sum()
    p.flags.writeable = False  # shared by every draw from this mix
    return tuple(n for n, _ in mix), p


def _road_layout(spec: SceneSpec, v: dict) -> RoadLayout:
    lanes = int(v["road.lanes_per_direction"])
    kind = v["road.type"]
    return RoadLayout(
        curvature=float(v["road.curvature"]) if kind == "curved" else 0.0,
        lanes=lanes, lane_width=float(v["road.lane_width"]),
        ego_lane=min(int(v["road.ego_lane"]), lanes - 1),
        sidewalk_width=float(v["road.sidewalk_width"]), curb_height=float(v["road.curb_height"]),
        parking=float(v["traffic.parking_occupancy"]) > 0, parking_sides=str(v["road.parking_sides"]),
        s_min=-spec.road.length_behind,
        s_max=max(spec.road.length_ahead, float(v["traffic.max_distance"]) + 20.0),
        cross_s=float(v["road.intersection_distance"]) if kind == "intersection" else None,
        cross_lanes=int(v["road.cross_lanes_per_direction"]) if kind == "intersection" else 0,
        profile=_profile(v), crown=float(v["road.crown"]))


def _profile(v: dict) -> VerticalProfile | None:
    """The road's vertical profile, or None for a flat road (both grades 0)."""
    ahead, behind = float(v["road.grade_ahead"]), float(v["road.grade_behind"])
    if ahead == 0.0 and behind == 0.0:
        return None
    return VerticalProfile(ahead, behind, float(v["road.vertical_k"]), float(v["road.vertical_start"]))


def _make_rig(spec: SceneSpec, v: dict, road: RoadLayout, actors: list[Actor]) -> CameraRig:
    rs = spec.rig
    if rs.type == "onboard":  # the LiDAR's mount (its spec) places the rig; the camera follows it
        from .lidar import preset

        mount = (0.0, 0.0, KITTI_LIDAR_HEIGHT) if spec.lidar is None else preset(spec.lidar.preset).mount_xyz
        return onboard_rig(mount)
    if rs.type == "gantry":  # over the road at s = 0, `lateral` metres left of the divider
        d = road.divider + float(v["rig.lateral"])
        return gantry_rig(float(v["rig.cam_height"]), float(v["rig.pan_deg"]), float(v["rig.tilt_deg"]),
                          float(v["rig.focal_px"]), tuple(road.xy(0.0, d)), rs.image_width,
                          rs.image_height)
    h = actors[0].recipe["dims"][0]  # the orbit target, actor 1, at the origin
    return orbit_rig(np.array([0.0, 0.0, h / 2]), float(v["rig.distance"]),
                     float(v["rig.elevation_deg"]), float(v["rig.azimuth_deg"]),
                     float(v["rig.focal_px"]), rs.image_width, rs.image_height)


def _scenery_params(spec: SceneSpec, v: dict, road: RoadLayout, seed: int, frame_index: int) -> dict:
    """The static world's parameters: kept in `World.scenery` so meta/ can rebuild it exactly."""
    scenery = {"road": road.to_dict(),
               "clutter": {k.split(".", 1)[1]: v[k] for k in v if k.startswith("clutter.")},
               "seed": int(factor_rng(seed, frame_index, "scenery").integers(2**31))}
    if spec.rig.type == "orbit":  # nothing static between the orbit camera and its target
        e, a = np.radians(float(v["rig.elevation_deg"])), np.radians(float(v["rig.azimuth_deg"]))
        reach = float(v["rig.distance"]) * np.cos(e) + 3.0
        sight = shapely.LineString([(0.0, 0.0), (reach * np.cos(a), reach * np.sin(a))]).buffer(3.0)
        scenery["keep_clear"] = [list(c) for c in sight.exterior.coords]
    return scenery


class _Traffic:
    """Places one frame's actors step by step; every step draws from the one `actors` stream, so
    the steps' order (and the draws' order within each) is part of the seed's meaning."""

    def __init__(self, spec: SceneSpec, v: dict, road: RoadLayout, obstacles: list[Obstacle],
                 rng: np.random.Generator, frontage: Frontage | None = None):
        self.spec, self.road, self.rng, self.frontage = spec, road, rng, frontage
        self.speed = float(v["traffic.speed"])
        self.sd_yaw = np.radians(float(v["traffic.heading_sd_deg"]))
        self.sd_lat = float(v["traffic.lateral_sd"])
        self.s_lo = max(road.s_min, -spec.road.length_behind)
        self.s_hi = min(road.s_max, float(v["traffic.max_distance"]))
        self.directions = [False, True] if spec.traffic.oncoming else [False]
        self.actors: list[Actor] = []
        self.placer = _Placer(obstacles, self._reserved())

    def _reserved(self) -> list[shapely.Polygon]:
        """Footprints no actor may take: the ego vehicle's, or the orbit target's (actor 1)."""
        rig_spec = self.spec.rig
        if rig_spec.type == "onboard":
            return [EGO_FOOTPRINT]
        if rig_spec.type == "orbit":
            recipe = _recipe(rig_spec.target_class, self.spec, self.rng)
            self.actors.append(Actor(1, rig_spec.target_class, build_actor_parts(recipe), np.eye(4),
                                     recipe=recipe))
            _, w, l = recipe["dims"]
            return [_footprint(np.eye(4), l, w)]
        return []

    def add(self, cls: str, recipe: dict, pose: np.ndarray, vel: float = 0.0,
            yaw_rate: float = 0.0, margin: float = MARGIN) -> None:
        """Adds the actor unless its footprint, grown by `margin`, collides; ids stay consecutive."""
        if not self.placer.try_place(pose, recipe, margin):
            return
        heading = pose[:3, 0]
        self.actors.append(Actor(len(self.actors) + 1, cls, build_actor_parts(recipe), pose,
                                 velocity=vel * heading, yaw_rate=yaw_rate, recipe=recipe))

    def lead(self, share: float, headway_s: float, ego_speed: float, column: float) -> None:
        """With probability `share`, a vehicle ahead of the ego in its lane, moving at the ego's
        speed, its rear the distance the ego covers in `headway_s` beyond the ego's free lane. In
        urban car following, time gaps are mostly 1-3 s (the two-second rule). With probability
        `column` it is the last of a column (`_column`). No draw at share 0 or column 0, so specs
        without car following or columns keep their worlds."""
        if not (share > 0 and self.spec.rig.type == "onboard" and self.spec.traffic.mix):
            return
        rng, road = self.rng, self.road
        if rng.uniform() >= share:
            return
        cls = _pick_class(self.spec.traffic.mix, rng)
        recipe = _recipe(cls, self.spec, rng)
        rear = EGO_FREE_AHEAD + MARGIN + ego_speed * headway_s  # beyond the free lane's margin
        s = rear + recipe["dims"][2] / 2 + 0.05  # 5 cm clear of it: footprints that touch collide
        d = road.lane_centre(road.ego_lane) + float(np.clip(rng.normal(0, self.sd_lat), -0.4, 0.4))
        if s > self.s_hi:  # beyond the traffic's reach (or the road's end): no vehicle to follow
            return
        self.add(cls, recipe, road.pose(s, d, 0.0, rng.normal(0, self.sd_yaw)), ego_speed,
                 ego_speed * road.curvature)
        if column > 0 and rng.uniform() < column:
            self._column(s + recipe["dims"][2] / 2, headway_s, ego_speed)

    def _column(self, front: float, headway_s: float, speed: float) -> None:
        """Vehicles nose to tail ahead of the lead in the ego's lane, from its `front` over
        QUEUE_LENGTH, all at the ego's speed: each the standstill gap (QUEUE_GAP) plus the distance
        covered in `headway_s` behind the next. Standing, a queue at a light or in a jam, seen
        from behind with each car hiding part of the next; moving, a platoon. It stops short of a
        cross street, as the queue beside the ego does."""
        road, rng = self.road, self.rng
        s, end = front, front + rng.uniform(*QUEUE_LENGTH)
        while True:
            s += rng.uniform(*QUEUE_GAP) + speed * headway_s
            cls = _pick_class(self.spec.traffic.mix, rng)
            recipe = _recipe(cls, self.spec, rng)
            l = recipe["dims"][2]
            if s >= min(end, self.s_hi) or road.in_cross_street(s + l / 2, l / 2 + 2.0):
                return
            d = road.lane_centre(road.ego_lane) + float(np.clip(rng.normal(0, self.sd_lat), -0.4, 0.4))
            self.add(cls, recipe, road.pose(s + l / 2, d, 0.0, rng.normal(0, self.sd_yaw)), speed,
                     speed * road.curvature)
            s += l

    def moving(self, dens: float) -> None:
        """Moving traffic, lane by lane; gaps exponential with the spec's mean density."""
        road, rng, mix = self.road, self.rng, self.spec.traffic.mix
        if not (mix and dens > 0):
            return
        for oncoming in self.directions:
            for lane in range(road.lanes):
                s = self.s_lo + rng.exponential(100.0 / dens)
                while s < self.s_hi:
                    cls = _pick_class(mix, rng)
                    recipe = _recipe(cls, self.spec, rng)
                    d = road.lane_centre(lane, oncoming) + float(
                        np.clip(rng.normal(0, self.sd_lat), -0.4, 0.4))
                    yaw = (np.pi if oncoming else 0.0) + rng.normal(0, self.sd_yaw)
                    vel = self.speed * rng.uniform(0.8, 1.2)
                    self.add(cls, recipe, road.pose(s, d, 0.0, yaw), vel,
                             (-1.0 if oncoming else 1.0) * vel * road.curvature)
                    s += recipe["dims"][2] + 2.0 + rng.exponential(100.0 / dens)

    def crossing(self, dens: float) -> None:
        """Traffic on the cross street, both ways, right-hand; lane i of the +y direction at
        x = cross_s + (i + 0.5) w."""
        road, rng, mix = self.road, self.rng, self.spec.traffic.mix
        if not (road.cross_s is not None and mix and dens > 0):
            return
        reach = VERGE_REACH
        for sign in (1.0, -1.0):
            for lane in range(road.cross_lanes):
                x = road.cross_s + sign * (lane + 0.5) * road.lane_width
                y = -reach + rng.exponential(100.0 / dens)
                while y < reach:
                    cls = _pick_class(mix, rng)
                    recipe = _recipe(cls, self.spec, rng)
                    yaw = sign * np.pi / 2 + rng.normal(0, self.sd_yaw)
                    T = np.eye(4)
                    T[:3, :3] = [[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]]
                    T[:3, 3] = [x + float(np.clip(rng.normal(0, self.sd_lat), -0.4, 0.4)), sign * y, 0.0]
                    self.add(cls, recipe, T, self.speed * rng.uniform(0.8, 1.2))
                    y += recipe["dims"][2] + 2.0 + rng.exponential(100.0 / dens)

    def queue(self, share: float) -> None:
        """With probability `share`, a queue of standing vehicles nose to tail in the lane beside
        the ego's: the next lane of its own direction where there is one, else the oncoming lane
        next to the divider. It stops short of a cross street. No draw at share 0."""
        if not (share > 0 and self.spec.rig.type == "onboard" and self.spec.traffic.mix):
            return
        road, rng = self.road, self.rng
        if rng.uniform() >= share:
            return
        oncoming = road.ego_lane + 1 >= road.lanes
        if oncoming and not self.spec.traffic.oncoming:
            return
        lane = road.lanes - 1 if oncoming else road.ego_lane + 1
        s = rng.uniform(*QUEUE_START)
        end = s + rng.uniform(*QUEUE_LENGTH)
        while s < min(end, self.s_hi):
            cls = _pick_class(self.spec.traffic.mix, rng)
            recipe = _recipe(cls, self.spec, rng)
            l = recipe["dims"][2]
            d = road.lane_centre(lane, oncoming) + float(np.clip(rng.normal(0, self.sd_lat), -0.4, 0.4))
            if road.in_cross_street(s + l / 2, l / 2 + 2.0):
                break
            yaw = (np.pi if oncoming else 0.0) + rng.normal(0, self.sd_yaw)
            self.add(cls, recipe, road.pose(s + l / 2, d, 0.0, yaw))
            s += l + rng.uniform(*QUEUE_GAP)

    def parked(self, occupancy: float) -> None:
        """Parked rows in the parking strips: bays nose to tail along each strip, each a vehicle's
        length and a gap (PARKED_GAP), each taken with probability `occupancy`; the vehicle
        within KERB_GAP of the kerb, its nose along the traffic on its side. Corners and side
        streets' mouths stay free (CORNER_CLEAR), and so do the drives and car-park entrances,
        which the scenery lays down as obstacles (simgen.scenery.lots._drive_mouth)."""
        road, rng = self.road, self.rng
        if not occupancy > 0:
            return
        for side in [k for k in (-1, 1) if road.parks(k)]:
            s = self.s_lo - rng.uniform(0.0, 5.0)  # the row's phase
            while s < self.s_hi:
                cls = _pick_class(PARKED_MIX, rng)
                recipe = _recipe(cls, self.spec, rng)
                _, w, l = recipe["dims"]
                taken, kerb = rng.uniform() < occupancy, rng.uniform(*KERB_GAP)
                yaw = (0.0 if side < 0 else np.pi) + rng.normal(0, self.sd_yaw)
                mid = s + l / 2
                if taken and not (road.in_cross_street(mid, l / 2 + CORNER_CLEAR)
                                  or self._in_mouth(side, mid, l / 2 + CORNER_CLEAR)):
                    d = (road.right_curb + w / 2 + kerb) if side < 0 else (road.left_curb - w / 2 - kerb)
                    self.add(cls, recipe, road.pose(mid, d, 0.0, yaw), margin=PARKED_MARGIN)
                s += l + rng.uniform(*PARKED_GAP)

    def _in_mouth(self, side: int, s: float, margin: float) -> bool:
        return self.frontage is not None and self.frontage.in_mouth(side, s, margin)

    def car_parks(self, occupancy: float) -> None:
        """Parked cars in the car parks' stalls (clutter.frontage), nose in or out, each stall
        taken with probability `occupancy`."""
        if self.frontage is None or not occupancy > 0:
            return
        rng = self.rng
        for stall in self.frontage.stalls:
            if rng.uniform() >= occupancy:
                continue
            cls = _pick_class(PARKED_MIX, rng)
            recipe = _recipe(cls, self.spec, rng)
            yaw = rng.choice([0.0, np.pi]) + rng.normal(0, self.sd_yaw)
            turn = np.eye(4)
            turn[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
            self.add(cls, recipe, stall @ turn)

    def pedestrians(self, dens: float) -> None:
        """Pedestrians on both sidewalks, walking either way."""
        road, rng, s_lo, s_hi = self.road, self.rng, self.s_lo, self.s_hi
        for side in (-1, 1):
            curb = road.right_curb if side < 0 else road.left_curb
            for s in rng.uniform(s_lo, s_hi, rng.poisson(dens * (s_hi - s_lo) / 100.0)):
                recipe = _recipe("Pedestrian", self.spec, rng)
                d = curb + side * rng.uniform(0.4, max(0.5, road.sidewalk_width - 0.4))
                if road.in_cross_street(s, 0.5) or self._in_mouth(side, s, 0.5):
                    continue  # the sidewalk stops at the cross street and at side streets
                yaw = rng.choice([0.0, np.pi]) + rng.normal(0, 0.4)
                self.add("Pedestrian", recipe, road.pose(s, d, road.curb_height, yaw), rng.uniform(0.8, 1.6))

    def cyclists(self, dens: float) -> None:
        """Cyclists at the outer edge of the outermost lane of each direction."""
        road, rng, s_lo, s_hi = self.road, self.rng, self.s_lo, self.s_hi
        for oncoming in self.directions:
            for s in rng.uniform(s_lo, s_hi, rng.poisson(dens * (s_hi - s_lo) / 100.0)):
                recipe = _recipe("Cyclist", self.spec, rng)
                edge = road.left_lane_edge if oncoming else road.right_lane_edge
                d = edge + (-0.7 if oncoming else 0.7)
                yaw = (np.pi if oncoming else 0.0) + rng.normal(0, self.sd_yaw)
                vel = rng.uniform(3.0, 7.0)
                self.add("Cyclist", recipe, road.pose(s, d, 0.0, yaw), vel,
                         (-1.0 if oncoming else 1.0) * vel * road.curvature)


def _place_actors(spec: SceneSpec, v: dict, road: RoadLayout, obstacles: list[Obstacle],
                  rng: np.random.Generator, frontage: Frontage | None = None) -> list[Actor]:
    """Every actor of the frame, in the fixed order that makes the seed reproducible."""
    traffic = _Traffic(spec, v, road, obstacles, rng, frontage)
    traffic.lead(float(v["traffic.lead_vehicle"]), float(v["traffic.headway_s"]),
                 float(v.get("rig.ego_speed", 0.0)), float(v["traffic.column"]))
    traffic.queue(float(v["traffic.queue"]))
    traffic.moving(float(v["traffic.vehicles_per_100m"]))
    traffic.crossing(float(v["traffic.vehicles_per_100m"]))
    traffic.parked(float(v["traffic.parking_occupancy"]))
    traffic.pedestrians(float(v["traffic.pedestrians_per_100m"]))
    traffic.cyclists(float(v["traffic.cyclists_per_100m"]))
    traffic.car_parks(float(v["traffic.car_park_occupancy"]))
    for actor in traffic.actors:  # planned on the flat road, then laid onto its profile
        drape_actor(actor, road)
    return traffic.actors


def _brake(actors: list[Actor], share: float, rng: np.random.Generator) -> None:
    """Lights the stop lamps of each moving vehicle with probability `share` (its own stream:
    the worlds of specs without braking keep every draw). Parked vehicles stay dark."""
    if not share > 0:
        return
    for actor in actors:
        if actor.cls in VEHICLE_CLASSES and actor.moving:
            actor.stop_lamps = bool(rng.uniform() < share)


def sample_world(spec: SceneSpec, seed: int, frame_index: int) -> World:
    """The world of one frame: a pure function of the spec, the seed and the frame index."""
    v = _values(spec, seed, frame_index)
    road = _road_layout(spec, v)
    scenery = _scenery_params(spec, v, road, seed, frame_index)
    plan = plan_frontage(scenery)
    static, obstacles = build_scenery(scenery, plan)
    actors = _place_actors(spec, v, road, obstacles, factor_rng(seed, frame_index, "actors"), plan)
    _brake(actors, float(v["traffic.braking"]), factor_rng(seed, frame_index, "braking"))
    rig = _make_rig(spec, v, road, actors)
    ego_velocity = np.array([float(v["rig.ego_speed"]), 0.0, 0.0]) if rig.kind == "onboard" else np.zeros(3)
    light = Light(v["light.time"], float(v["light.sun_intensity"]),
                  float(v["light.sun_elevation_deg"]), float(v["light.sun_azimuth_deg"]))
    weather = Weather(float(v["weather.fog_extinction"]), float(v["weather.rain_rate"]),
                      float(v["weather.wind"]))
    appearance = Appearance(**{k: _plain(v[f"appearance.{k}"]) for k in Appearance.__dataclass_fields__})
    camera = CameraResponse(**{k: _plain(v[f"camera.{k}"]) for k in CameraResponse.__dataclass_fields__})
    return World(actors=actors, static=static, weather=weather,
                 lidar_pose=rig.reference_pose.copy(), ego_velocity=ego_velocity, rig=rig,
                 light=light, appearance=appearance, camera=camera, sensor=str(v["sensor"]),
                 scenery=scenery, seed=int(seed),
                 frame_index=int(frame_index))
