"""Sweeps: the same worlds re-scanned with other sensors, lifted and evaluated at every point.

A sweep spec names the scenes and the axes. Every scan configuration re-scans the worlds of the
scene's base dataset (`simgen.rescan`) or drops rings from its native scan (`kitti.reduce`, the
thesis's way), so across a sweep the images and labels are byte-identical and only the LiDAR
changes. Frames and points are independent jobs on the run's one backend; each stage marks itself
done on disk, so a stopped sweep resumes where it stopped.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import yaml
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator

from kitti.jobs import Backend
from lifter.methods import METHODS

from . import stages

if TYPE_CHECKING:
    from simgen.rescan import RescanRequest


class SceneRef(BaseModel):
    model_config = ConfigDict(extra="forbid")
    spec: Path
    frames: int | None = Field(default=None, gt=0)
    seed: int | None = None


class LidarWeather(BaseModel):
    """Weather the LiDAR sees at a sweep point (the images keep the world's own)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    fog_extinction: float = Field(0.0, ge=0.0)  # beta, 1/m
    rain_rate: float = Field(0.0, ge=0.0)  # mm/h


def _known_method(name: str) -> str:
    if name not in METHODS:
        raise ValueError(f"unknown lifting method '{name}' (one of {', '.join(METHODS)})")
    return name


MethodName = Annotated[str, AfterValidator(_known_method)]  # a name of lifter.methods.METHODS


class Axes(BaseModel):
    model_config = ConfigDict(extra="forbid")
    lidar: list[str] = ["hdl64e"]
    beams: list[int] = [64]
    beam_mode: list[Literal["native", "dropped"]] = ["native"]
    max_range: list[float | None] = [None]
    weather: list[LidarWeather | None] = [None]  # None: the world's own weather
    method: list[MethodName] = ["fit"]
    boxes: list[Literal["gt", "detector"]] = ["gt"]  # 2D boxes from the labels or the detector

    @field_validator("beams")
    @classmethod
    def _positive(cls, v: list[int]) -> list[int]:
        if any(b <= 0 for b in v):
            raise ValueError("beam counts must be positive")
        return v



class SweepSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    name: str
    scenes: list[SceneRef] = Field(min_length=1)
    axes: Axes = Axes()
    split: str = "val"
    range_bins: list[float] = [0, 10, 20, 30, 40, 50, 60, 70, 80, float("inf")]
    data_dir: Path = Path("data/sweeps")


class SweepSpecError(ValueError):
    """A sweep spec that does not validate; the message names the file and the key."""


def load_sweep(path: Path) -> SweepSpec:
    try:
        raw = yaml.safe_load(Path(path).read_text())
    except yaml.YAMLError as e:
        raise SweepSpecError(f"{path}: not valid YAML: {e}") from None
    try:
        spec = SweepSpec.model_validate(raw)
    except ValidationError as e:
        msgs = "; ".join(f"key '{'.'.join(str(p) for p in err['loc'])}': {err['msg']}"
                         for err in e.errors())
        raise SweepSpecError(f"{path}: {msgs}") from None
    for scene in spec.scenes:  # spec paths are relative to the sweep file's folder or the cwd
        if not scene.spec.is_absolute() and not scene.spec.exists():
            scene.spec = Path(path).parent / scene.spec
        if not scene.spec.exists():
            raise SweepSpecError(f"{path}: key 'scenes.spec': file {scene.spec} not found")
    return spec


@dataclass(frozen=True)
class ScanConfig:
    """One scan of a sweep. `beams` is always the number of lasers the scan has; the mode says how
    a count other than the sensor's own is made: `native` scans with a sensor built with that many
    lasers (the preset's own table at its own count, else `uniform` lasers spaced evenly over the
    HDL-64E's vertical field), `dropped` keeps every k-th ring of the preset's own scan."""

    lidar: str
    beams: int
    mode: str  # native | dropped
    max_range: float | None
    weather: LidarWeather | None = None

    @property
    def sensor(self) -> str:
        """The preset that makes the scan: the named one, or `uniform` for a native count it lacks."""
        if self.mode == "dropped" or self.beams == own_beams(self.lidar):
            return self.lidar
        return "uniform"

    @property
    def key(self) -> str:
        """The scan's folder name: sensor, beams, mode, range and weather."""
        rng = "max" if self.max_range is None else f"{self.max_range:g}m"
        return f"{self.sensor}-{self.beams}b-{self.mode}-{rng}{weather_suffix(self.weather)}"

    def parent(self) -> ScanConfig:
        """The native scan at the preset's own count that a dropped scan keeps rings of."""
        return ScanConfig(self.lidar, own_beams(self.lidar), "native", self.max_range, self.weather)


def own_beams(lidar: str) -> int:
    """The preset's own beam count (`uniform`: its default)."""
    from simgen.lidar import preset

    return preset(lidar).beams


def weather_suffix(w: LidarWeather | None) -> str:
    if w is None:
        return ""
    return (f"-fog{w.fog_extinction:g}" if w.fog_extinction else "") + \
        (f"-rain{w.rain_rate:g}" if w.rain_rate else "") or "-clear"


@dataclass(frozen=True)
class Point:
    """One evaluated configuration: a scene, a scan, a lifting method and a source of 2D boxes."""

    scene: str
    scan: ScanConfig | None  # None for methods that need no scan: independent of the LiDAR
    method: str
    boxes: str  # gt | detector

    @property
    def key(self) -> str:
        scan = self.scan.key if self.scan else "no-lidar"
        return f"{self.scene}/{scan}/{self.method}-{self.boxes}"


@dataclass
class Plan:
    spec: SweepSpec
    root: Path
    scans: list[ScanConfig] = field(default_factory=list)
    points: list[Point] = field(default_factory=list)

    @cached_property
    def versions(self) -> tuple[str, str]:
        """(`generator_key`, `models_key`), taken once: every stage of a run and whatever reads its
        folders afterwards (`testbed.uncertainty`) name the same folders, even where the code
        changes while it runs."""
        return generator_key(), models_key()

    def points_dir(self, models: str) -> Path:
        """Lifted boxes and evaluations, per set of model weights."""
        return self.root / f"points-{models}"

    def base_dir(self, scene: str, generator: str) -> Path:
        """A scene's generated frames, per version of the generator (`generator_key`)."""
        return self.root / scene / f"base-{generator}"

    def scan_dir(self, scene: str, generator: str, scan: ScanConfig) -> Path:
        """One scan configuration of a scene's worlds, per version of the generator."""
        return self.root / scene / f"scans-{generator}" / scan.key

    def data_dir(self, pt: Point, generator: str) -> Path:
        """The dataset a point lifts from: its scan of the scene's worlds, or the generated frames
        themselves for a method that needs no scan."""
        if pt.scan is None:
            return self.base_dir(pt.scene, generator)
        return self.scan_dir(pt.scene, generator, pt.scan)

    def point_dir(self, pt: Point, generator: str, models: str) -> Path:
        """A point's lifted boxes (`pred/`) and evaluation (`eval.json`)."""
        return self.points_dir(f"{generator}-{models}") / pt.key


def plan(spec: SweepSpec, root: Path | None = None) -> Plan:
    """All scan configurations and points of the sweep, in a fixed order."""
    ax = spec.axes
    scans: list[ScanConfig] = []
    for lidar, beams, mode, rng, weather in itertools.product(ax.lidar, ax.beams, ax.beam_mode,
                                                              ax.max_range, ax.weather):
        own = own_beams(lidar)
        if mode == "dropped" and (beams >= own or own % beams):
            continue  # rings are dropped from the preset's own scan: only divisors below its count
        scans.append(ScanConfig(lidar, beams, mode, rng, weather))
    for s in list(scans):  # a dropped scan needs its native parent
        if s.mode == "dropped" and s.parent() not in scans:
            scans.insert(0, s.parent())
    points = []
    for scene in spec.scenes:
        name = scene_name(scene)
        for method, boxes in itertools.product(ax.method, ax.boxes):
            if METHODS[method].needs_scan:
                points += [Point(name, s, method, boxes) for s in scans]
            else:
                points.append(Point(name, None, method, boxes))
    return Plan(spec, root or spec.data_dir / spec.name, scans, points)


def scene_name(scene: SceneRef) -> str:
    return f"{scene.spec.stem}-{stages.digest(scene.spec, scene.frames, scene.seed)}"


def rescan_request(c: ScanConfig) -> RescanRequest:
    """The simulator request of a native scan configuration: its sensor (`ScanConfig.sensor`)
    with `beams` lasers."""
    from simgen.rescan import RescanRequest, WeatherOverride
    from simgen.spec import LidarSection

    beams = c.beams if c.sensor == "uniform" else None  # a real preset at its own count
    weather = None if c.weather is None else WeatherOverride(c.weather.fog_extinction,
                                                             c.weather.rain_rate)
    return RescanRequest(LidarSection(preset=c.sensor, beams=beams, max_range=c.max_range), weather)


def _code(*packages) -> list[Path]:
    """Every Python file of the packages, in a fixed order."""
    return [f for pkg in packages for f in sorted(Path(pkg.__file__).parent.rglob("*.py"))]


def models_key() -> str:
    """Digest of the shipped detector and lifter weights and of their code (and the evaluation's,
    in kitti): results made with other weights or another version of the detector, the lifter or
    the metric are never taken from the cache."""
    import detector
    import kitti
    import lifter
    from detector.infer import DEFAULT_WEIGHTS as DETECTOR
    from lifter.predictor import DEFAULT_WEIGHTS as LIFTER

    return stages.digest(DETECTOR, LIFTER, *_code(detector, lifter, kitti))


def generator_key() -> str:
    """Digest of the scene generator's code (simgen, and kitti, which writes the files): frames and
    scans made by another version of the generator are never taken from the cache."""
    import kitti
    import simgen

    return stages.digest(*_code(simgen, kitti))


def execute(p: Plan, backend: Backend) -> list[tuple[Point, dict]]:
    """Run every stage not yet marked done on `backend`; return each point with its evaluation."""
    spec = p.spec
    generator, models = p.versions
    bases, detections = {}, {}
    for scene in spec.scenes:
        name = scene_name(scene)
        bases[name] = stages.generate(scene.spec, p.base_dir(name, generator), scene.frames,
                                      scene.seed, backend)
        if "detector" in spec.axes.boxes:
            detections[name] = stages.detect(bases[name],
                                             p.root / name / f"detections-{generator}-{models}",
                                             spec.split)
    scan_dirs = {(n, c): p.scan_dir(n, generator, c) for n in bases for c in p.scans}
    stages.rescan([stages.Rescan(bases[n], d, rescan_request(c))
                   for (n, c), d in scan_dirs.items() if c.mode == "native"], backend)
    stages.reduce_beams([stages.Reduction(scan_dirs[n, c.parent()], d, c.beams)
                         for (n, c), d in scan_dirs.items() if c.mode == "dropped"], backend)
    jobs = []
    for pt in p.points:
        dets = detections[pt.scene] if pt.boxes == "detector" else None
        jobs.append(stages.LiftJob(p.data_dir(pt, generator), dets, pt.method, spec.split,
                                   p.point_dir(pt, generator, models), tuple(spec.range_bins)))
    results = backend.map(stages.lift_and_evaluate, jobs, desc="points")
    return list(zip(p.points, results))
