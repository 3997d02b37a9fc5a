"""Scene specs (`scenes/*.yaml`): validated on load, every error names the key and the file.

Every physical parameter is a factor (simgen.factors): a fixed value, `{range: [lo, hi]}`,
`{choice: [...]}` or `{steps: [lo, hi, n]}`, sampled per frame from the seed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .factors import factor

VEHICLE_CLASSES = ("Car", "Van", "Truck", "Bus")
# What an actor can be labelled (KITTI's types the generator builds).
ActorClass = Literal["Car", "Van", "Truck", "Bus", "Pedestrian", "Cyclist", "Misc"]
# Kinds of lot beside the street (clutter.frontage; simgen.scenery builds them).
FRONTAGE_KINDS = ("row", "houses", "open", "green", "car_park")


class SpecError(ValueError):
    """A scene spec that cannot be used; the message names the file and the key."""


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


def _weights(v: dict[str, float], allowed: tuple[str, ...], what: str) -> dict[str, float]:
    """A mix of named weights: known names, none negative, not all zero."""
    for k, w in v.items():
        if k not in allowed:
            raise ValueError(f"unknown {what} {k!r} (allowed: {list(allowed)})")
        if w < 0:
            raise ValueError(f"weight of {k} is negative")
    if v and sum(v.values()) <= 0:
        raise ValueError("the weights sum to zero")
    return v


class SplitSpec(Strict):
    train_fraction: float = Field(0.5, gt=0.0, lt=1.0)


class RoadSpec(Strict):
    """A road along +x through the ego position; lanes of both directions, curbs and sidewalks."""

    type: factor(str, options=("straight", "curved", "intersection")) = "straight"
    lanes_per_direction: factor(int, 1, 4) = 2
    lane_width: factor(float, 2.5, 4.5) = 3.5
    curvature: factor(float, -0.01, 0.01) = 0.0  # 1/m, left positive; used when type is curved
    intersection_distance: factor(float, 10.0, 150.0) = 35.0  # m ahead; type intersection
    cross_lanes_per_direction: factor(int, 1, 3) = 1  # on the cross street
    ego_lane: factor(int, 0, 3) = 0  # counted from the right curb, clipped to the lanes present
    sidewalk_width: factor(float, 1.0, 8.0) = 3.0
    # The curbs lined by a parking strip (simgen.road.PARKING_WIDTH) when traffic.parking_occupancy
    # is above 0: both, the right one (the ego's side), the left one, or none.
    parking_sides: factor(str, options=("both", "right", "left", "none")) = "both"
    curb_height: factor(float, 0.0, 0.3) = 0.15
    length_ahead: float = Field(160.0, ge=20.0, le=400.0)
    length_behind: float = Field(40.0, ge=0.0, le=200.0)
    # The vertical profile (simgen.road.VerticalProfile): the grade reached ahead of and behind
    # the ego, relative to the ego's own (rise per metre), on parabolic vertical curves of K metres
    # per percent of grade change that begin `vertical_start` metres from the ego. All grades 0
    # (the default): a flat world.
    grade_ahead: factor(float, -0.15, 0.15) = 0.0
    grade_behind: factor(float, -0.15, 0.15) = 0.0
    vertical_k: factor(float, 2.0, 200.0) = 20.0
    vertical_start: factor(float, 0.0, 200.0) = 0.0
    # The carriageway's cross slope each side of its crown at the divider (fall per metre;
    # simgen.road.RoadLayout.crown). 0 (the default): flat across.
    crown: factor(float, 0.0, 0.08) = 0.0


class TrafficSpec(Strict):
    vehicles_per_100m: factor(float, 0.0, 30.0) = 2.0  # per moving lane
    # Moving traffic's classes: one Van to ten Cars as in KITTI's training labels (2,914 Vans,
    # 28,742 Cars); Trucks 8 % (parked vehicles are Cars and Vans only, simgen.sample.PARKED_MIX,
    # so about 3 % of all vehicles, KITTI's share: 1,094 of 32,750).
    mix: dict[str, float] = Field(
        default_factory=lambda: {"Car": 0.835, "Van": 0.085, "Truck": 0.08})
    # The share of a parking strip's bays taken (simgen.sample._Traffic.parked): the strip is laid
    # out as bays nose to tail, each a vehicle's length plus a gap, and each holds a parked vehicle
    # with this probability. German kerbside surveys find 67-96 % taken in residential streets.
    parking_occupancy: factor(float, 0.0, 1.0) = 0.3
    # The probability of a queue of standing vehicles in the lane beside the ego's (the next lane
    # of its own direction where there is one, else the oncoming lane): traffic held at a light or
    # in a jam (simgen.sample._Traffic.queue).
    queue: factor(float, 0.0, 1.0) = 0.0
    pedestrians_per_100m: factor(float, 0.0, 50.0) = 3.0  # per sidewalk
    cyclists_per_100m: factor(float, 0.0, 20.0) = 0.5  # per direction
    max_distance: factor(float, 10.0, 400.0) = 120.0  # along the road, ahead of the sensor
    # Car following (simgen.sample._Traffic.lead): the probability that a vehicle drives ahead of
    # the ego in its lane, at the ego's speed, `headway_s` seconds ahead of the ego's free lane.
    lead_vehicle: factor(float, 0.0, 1.0) = 0.0
    headway_s: factor(float, 0.0, 10.0) = 2.0
    # The probability that the lead vehicle is the last of a column in the ego's lane, vehicles nose
    # to tail ahead of it at the ego's speed (simgen.sample._Traffic._column): standing, the queue
    # the ego waits in at a light or in a jam; moving, a platoon.
    column: factor(float, 0.0, 1.0) = 0.0
    car_park_occupancy: factor(float, 0.0, 1.0) = 0.5  # share of car-park stalls taken (frontage)
    speed: factor(float, 0.0, 40.0) = 12.0  # m/s of moving traffic
    # The share of the vehicles moving faster than 0.5 m/s whose stop lamps are lit, as they brake
    # (simgen.sample._brake). None by default: how many of KITTI's cars brake is not published.
    braking: factor(float, 0.0, 1.0) = 0.0
    heading_sd_deg: factor(float, 0.0, 30.0) = 2.0
    lateral_sd: factor(float, 0.0, 1.0) = 0.2
    oncoming: bool = True

    @field_validator("mix")
    @classmethod
    def _mix(cls, v: dict[str, float]) -> dict[str, float]:
        return _weights(v, VEHICLE_CLASSES, "vehicle class")


class ClutterSpec(Strict):
    # 003's scene types: city (buildings), grass, forest (woods beside the road), desert (sand).
    environment: factor(str, options=("city", "grass", "forest", "desert")) = "city"
    buildings: bool = True
    building_setback: factor(float, 0.0, 30.0) = 1.0  # metres behind the sidewalk
    trees_per_100m: factor(float, 0.0, 40.0) = 4.0  # per side
    pole_spacing: factor(float, 0.0, 200.0) = 30.0  # metres; 0 = no poles
    fences: bool = False
    # What stands behind each sidewalk (simgen.scenery, "Frontage"): the weight of each kind of
    # lot, drawn lot by lot along each side. row: a closed row of buildings `building_setback`
    # behind the sidewalk; houses: detached houses behind front yards (hedges, fences, walls,
    # shrubs), gaps between them, a second row across the block; open: a lawn or a meadow with
    # park trees, the next street's buildings across the block; green: a belt of shrubs and small
    # trees behind a grass margin, the same buildings behind it; car_park: rows of stalls with
    # parked cars (traffic.car_park_occupancy), trees, a store behind. Empty: the first street
    # model, one closed row along the whole street. Needs the city environment with buildings on
    # (elsewhere it is ignored).
    frontage: dict[str, float] = Field(default_factory=dict)
    side_streets_per_100m: factor(float, 0.0, 5.0) = 0.0  # T-junctions per side; with frontage
    # Share of open lots with a steel crash barrier along the sidewalk (simgen.scenery._guardrail).
    guardrail: factor(float, 0.0, 1.0) = 0.0
    # Share of closed rows behind front gardens, open lots and belts of green with a hedge, fence or
    # wall along the sidewalk (simgen.scenery._front_boundaries); detached houses always had theirs.
    front_boundary: factor(float, 0.0, 1.0) = 0.0
    # Street furniture on the sidewalks (simgen.scenery, "Street furniture"): a factor on the
    # documented densities of traffic signs, litter bins, bollards and cycle stands; traffic
    # signals at the intersection whenever > 0. 0: none (as before).
    furniture: factor(float, 0.0, 5.0) = 1.0

    @field_validator("frontage")
    @classmethod
    def _frontage(cls, v: dict[str, float]) -> dict[str, float]:
        return _weights(v, FRONTAGE_KINDS, "lot kind")


class OnboardRig(Strict):
    """KITTI's car rig: the real KITTI calibration, LiDAR 1.73 m above the road."""

    type: Literal["onboard"] = "onboard"
    ego_speed: factor(float, 0.0, 40.0) = 10.0


class GantryRig(Strict):
    """004 roadside camera: height, pan, tilt, one focal length, principal point at the centre."""

    type: Literal["gantry"]
    cam_height: factor(float, 2.0, 30.0) = 6.5
    pan_deg: factor(float, -90.0, 90.0) = 0.0
    tilt_deg: factor(float, 0.0, 89.0) = 20.0
    focal_px: factor(float, 100.0, 5000.0) = 1000.0
    lateral: factor(float, -30.0, 30.0) = 0.0  # camera offset left of the road centre, m
    image_width: int = Field(1242, ge=32, le=4096)
    image_height: int = Field(375, ge=32, le=4096)


class OrbitRig(Strict):
    """003 camera around a target vehicle: distance, elevation, azimuth (0 = in front of it)."""

    type: Literal["orbit"]
    distance: factor(float, 3.0, 500.0) = 30.0
    elevation_deg: factor(float, 0.0, 89.0) = 20.0
    azimuth_deg: factor(float, -360.0, 360.0) = 0.0
    focal_px: factor(float, 100.0, 5000.0) = 721.5377
    target_class: Literal["Car", "Van", "Truck", "Bus"] = "Car"
    image_width: int = Field(1242, ge=32, le=4096)
    image_height: int = Field(375, ge=32, le=4096)


class LightSpec(Strict):
    time: factor(str, options=("day", "dusk", "night")) = "day"
    sun_intensity: factor(float, 0.0, 1.0) = 1.0  # share of full sun
    sun_elevation_deg: factor(float, 0.0, 90.0) = 45.0
    sun_azimuth_deg: factor(float, -360.0, 360.0) = 30.0  # from world +x towards +y


class AppearanceSpec(Strict):
    """What the camera sees of surfaces and sky (simgen.render, simgen.textures)."""

    textures: bool = True  # procedural surface detail on the scenery
    shadows: bool = True  # the sun's shadows (day and dusk)
    cloud_cover: factor(float, 0.0, 1.0) = 0.3  # share of the sky under cloud
    colour_jitter: factor(float, 0.0, 1.0) = 0.08  # log sd of the scenery's colour gains per frame


class CameraSpec(Strict):
    """The colour camera's response (simgen.camera; defaults: KITTI's Flea2 colour cameras)."""

    exposure_ev: factor(float, -4.0, 4.0) = 0.0  # offset from the auto-exposure, in stops
    white_balance_sd: factor(float, 0.0, 0.5) = 0.03  # log sd of the red and blue gains
    corner_illumination: factor(float, 0.2, 1.0) = 0.75  # vignetting at the image corner
    # The lens blur, output pixels. With `rectified` the rectification's own (0.26 px^2 at the
    # centre, simgen.camera) comes on top: the default 0.5 of lens and rectification together
    # leaves nothing for the lens in quadrature.
    blur_sigma_px: factor(float, 0.0, 5.0) = 0.0
    full_well_e: factor(float, 0.0, 1e6) = 10000.0  # electrons at the white level; 0 = no noise
    read_noise_e: factor(float, 0.0, 1000.0) = 10.0
    bayer: bool = True  # RGGB colour filter array and demosaicing
    # with bayer: the array on KITTI's raw camera pixels (its lens distortion and finer pitch),
    # then rectified back to the output's pixels as KITTI's frames were (simgen.camera)
    rectified: bool = True
    # The output curve: 1.4 is KITTI-like (simgen.camera.KEY), 2.2 sRGB-like, 1 linear.
    gamma: factor(float, 1.0, 3.0) = 1.4


class WeatherSpec(Strict):
    fog_extinction: factor(float, 0.0, 0.3) = 0.0  # beta, 1/m; visibility ~ 3/beta
    rain_rate: factor(float, 0.0, 100.0) = 0.0  # mm/h
    wind: factor(float, 0.0, 30.0) = 0.0  # m/s


class LabelRules(Strict):
    """Which objects get a full label, which a DontCare row (thresholds documented in labels.py)."""

    min_height_px: float = Field(10.0, ge=0.0)
    max_distance: float = Field(80.0, gt=0.0)
    min_visible_share: float = Field(0.1, ge=0.0, le=1.0)
    occlusion_partly_below: float = Field(0.8, gt=0.0, le=1.0)  # visible share < this -> 1
    occlusion_largely_below: float = Field(0.3, gt=0.0, le=1.0)  # visible share < this -> 2
    # Classes whose 2D box takes its left and right sides from the mesh's silhouette, top and
    # bottom from the 3D box's projection. KITTI's object devkit: a fixed-size box fits a
    # pedestrian badly, so its left/right boundaries were labelled again in the image (Mechanical
    # Turk); every other class's 2D box is the projection.
    silhouette_sides: tuple[ActorClass, ...] = ("Pedestrian",)
    # An object with fewer LiDAR returns on it than this gets a DontCare row (0: no such rule;
    # needs a LiDAR). KITTI's annotators drew their boxes in the Velodyne point clouds, and its
    # devkit says its DontCare regions are objects left unlabelled "because they have been too
    # far away from the laser scanner".
    min_lidar_points: int = Field(0, ge=0)

    @model_validator(mode="after")
    def _order(self) -> "LabelRules":
        if self.occlusion_largely_below > self.occlusion_partly_below:
            raise ValueError("occlusion_largely_below must not exceed occlusion_partly_below")
        return self


class LidarSection(Strict):
    """Passed through untouched to simgen.lidar.preset(preset, beams, max_range)."""

    preset: str
    beams: int | None = Field(None, ge=1)
    max_range: float | None = Field(None, gt=0.0)


class UserMeshSpec(Strict):
    """A mesh file trimesh loads (OBJ/GLB/PLY...), frame x forward, y left, z up (or up: y)."""

    path: str
    cls: ActorClass
    size: tuple[float, float, float] | None = None  # target h, w, l in metres
    share: float = Field(1.0, ge=0.0, le=1.0)  # share of the class's actors that use it
    up: Literal["z", "y"] = "z"
    color: tuple[float, float, float] = (0.5, 0.5, 0.5)
    reflectivity: float = Field(0.3, ge=0.0, le=1.0)

    @field_validator("size")
    @classmethod
    def _size(cls, v):
        if v is not None and min(v) <= 0:
            raise ValueError("size entries h, w, l must be positive")
        return v


class SceneSpec(Strict):
    name: str
    frames: int = Field(8, ge=1)
    seed: int = Field(0, ge=0)
    split: SplitSpec = SplitSpec()
    road: RoadSpec = RoadSpec()
    traffic: TrafficSpec = TrafficSpec()
    clutter: ClutterSpec = ClutterSpec()
    rig: Annotated[OnboardRig | GantryRig | OrbitRig, Field(discriminator="type")] = OnboardRig()
    light: LightSpec = LightSpec()
    weather: WeatherSpec = WeatherSpec()
    appearance: AppearanceSpec = AppearanceSpec()
    camera: CameraSpec = CameraSpec()
    sensor: factor(str, options=("normal", "night_vision", "thermal")) = "normal"
    labels: LabelRules = LabelRules()
    lidar: LidarSection | None = None
    user_meshes: list[UserMeshSpec] = Field(default_factory=list)

    @field_validator("lidar", mode="before")
    @classmethod
    def _lidar_none(cls, v: Any) -> Any:
        return None if v in ("none", "None", False) else v

    @model_validator(mode="after")
    def _labels_need_lidar(self) -> "SceneSpec":
        if self.labels.min_lidar_points and self.lidar is None:
            raise ValueError("labels.min_lidar_points counts LiDAR returns: the spec needs a lidar")
        return self


def _format_errors(err: ValidationError, path: Path) -> str:
    lines = []
    for e in err.errors():
        key = ".".join(str(p) for p in e["loc"]) or "<top level>"
        msg = e["msg"].removeprefix("Value error, ")
        lines.append(f"{path}: key '{key}': {msg}")
    return "\n".join(lines)


def spec_from_dict(data: Any, path: str | Path = "<spec>") -> SceneSpec:
    path = Path(path)
    if not isinstance(data, dict):
        raise SpecError(f"{path}: the spec must be a mapping of keys, got {type(data).__name__}")
    try:
        spec = SceneSpec.model_validate(data)
    except ValidationError as e:
        raise SpecError(_format_errors(e, path)) from None
    for i, um in enumerate(spec.user_meshes):
        p = Path(um.path)
        if not p.is_absolute():
            p = path.parent / p
        if not p.is_file():
            raise SpecError(f"{path}: key 'user_meshes.{i}.path': no such file {p}")
    return spec


def load_spec(path: str | Path) -> SceneSpec:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as e:
        raise SpecError(f"{path}: cannot read the spec: {e.strerror}") from None
    except yaml.YAMLError as e:
        raise SpecError(f"{path}: not valid YAML: {e}") from None
    spec = spec_from_dict(data, path)
    # User mesh paths are relative to the spec file: make them absolute once, here.
    if spec.user_meshes:
        fixed = [um.model_copy(update={"path": str((path.parent / um.path).resolve())})
                 for um in spec.user_meshes]
        spec = spec.model_copy(update={"user_meshes": fixed})
    return spec


def spec_to_dict(spec: SceneSpec) -> dict:
    """JSON-able form that validates back to the same spec."""
    return spec.model_dump(mode="json")
