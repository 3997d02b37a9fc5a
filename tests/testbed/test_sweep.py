"""Sweep planning, spec validation, backends and the report tables."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from testbed.backends import BLAS_THREAD_VARS, LocalBackend, RayBackend
from testbed.report import metric_rows, range_table, summary_table
from testbed.stages import digest
from testbed.sweep import (
    LidarWeather,
    Point,
    ScanConfig,
    SweepSpec,
    SweepSpecError,
    load_sweep,
    plan,
    rescan_request,
)

ROOT = Path(__file__).resolve().parents[2]


def _write(tmp_path: Path, text: str) -> Path:
    (tmp_path / "scene.yaml").write_text("name: x\n")
    path = tmp_path / "sweep.yaml"
    path.write_text(text)
    return path


def test_plan_expands_axes_and_adds_the_parent_of_dropped_scans(tmp_path):
    spec = load_sweep(_write(tmp_path, """
name: s
scenes: [{spec: scene.yaml, frames: 3, seed: 5}]
axes: {beams: [128, 32, 24, 16], beam_mode: [dropped], method: [fit, mono], boxes: [gt, detector]}
"""))
    p = plan(spec)
    # 128 and 24 cannot be dropped from 64 rings; the 64-beam native parent is added first
    assert [s.key for s in p.scans] == ["hdl64e-64b-native-max", "hdl64e-32b-dropped-max",
                                        "hdl64e-16b-dropped-max"]
    lidar_points = [pt for pt in p.points if pt.method == "fit"]
    assert len(lidar_points) == 3 * 2 and all(pt.scan is not None for pt in lidar_points)
    mono = [pt for pt in p.points if pt.method == "mono"]
    assert len(mono) == 2 and all(pt.scan is None for pt in mono)  # image-only: once per box source
    assert len({pt.key for pt in p.points}) == len(p.points)


@pytest.mark.parametrize("body,key", [
    ("name: s\nscenes: [{spec: scene.yaml}]\naxes: {beams: [0]}\n", "axes.beams"),
    ("name: s\nscenes: [{spec: scene.yaml}]\naxes: {bems: [16]}\n", "axes.bems"),
    ("name: s\nscenes: [{spec: scene.yaml}]\naxes: {method: [magic]}\n", "axes.method.0"),
    ("name: s\nscenes: [{spec: missing.yaml}]\n", "scenes.spec"),
    ("name: s\nscenes: []\n", "scenes"),
])
def test_sweep_spec_errors_name_the_file_and_key(tmp_path, body, key):
    path = _write(tmp_path, body)
    with pytest.raises(SweepSpecError) as e:
        load_sweep(path)
    assert str(path) in str(e.value) and f"key '{key}'" in str(e.value)


def test_committed_sweeps_validate():
    sweeps = sorted((ROOT / "scenes" / "sweeps").glob("*.yaml"))
    assert len(sweeps) >= 3
    for f in sweeps:
        assert plan(load_sweep(f)).points


def test_native_scans_use_the_preset_at_its_own_count_else_a_uniform_sensor():
    def sensor(lidar, beams):
        lidar_section = rescan_request(ScanConfig(lidar, beams, "native", None)).lidar
        return lidar_section.preset, lidar_section.beams

    assert sensor("hdl64e", 64) == ("hdl64e", None)
    assert sensor("hdl64e", 16) == ("uniform", 16)
    assert sensor("vlp16", 16) == ("vlp16", None)
    assert sensor("uniform", 128) == ("uniform", 128)
    weather = LidarWeather(fog_extinction=0.03)
    request = rescan_request(ScanConfig("hdl64e", 64, "native", 40.0, weather))
    assert request.record() == {"preset": "hdl64e", "beams": 64, "max_range": 40.0,
                                "weather": {"fog_extinction": 0.03, "rain_rate": 0.0}}


def test_scan_folders_name_the_sensor_and_the_mode():
    assert ScanConfig("hdl64e", 64, "native", None).key == "hdl64e-64b-native-max"
    assert ScanConfig("hdl64e", 16, "native", None).key == "uniform-16b-native-max"
    assert ScanConfig("hdl64e", 16, "dropped", 40.0).key == "hdl64e-16b-dropped-40m"
    assert ScanConfig("vlp16", 8, "dropped", None).parent() == ScanConfig("vlp16", 16, "native", None)
    spec = SweepSpec(name="s", scenes=[{"spec": ROOT / "scenes/golden/street.yaml"}],
                     axes={"lidar": ["vlp16"], "beams": [16, 8, 4, 3], "beam_mode": ["dropped"]})
    assert [c.key for c in plan(spec).scans] == ["vlp16-16b-native-max", "vlp16-8b-dropped-max",
                                                 "vlp16-4b-dropped-max"]


def test_backends_return_results_in_job_order():
    jobs = list(range(7))  # jobs must be importable by the workers: an installed module's function
    want = [digest(j) for j in jobs]
    assert LocalBackend(1).map(digest, jobs) == want
    assert LocalBackend(2).map(digest, jobs) == want
    ray = pytest.importorskip("ray")
    try:
        assert RayBackend(workers=2).map(digest, jobs) == want
    finally:
        ray.shutdown()


def test_pool_workers_start_with_one_blas_thread_each(monkeypatch):
    """A pool fills the cores with processes: each worker's BLAS must not start a thread per core
    on top (they spun against each other; results/fidelity/README.md)."""
    for var in BLAS_THREAD_VARS:
        monkeypatch.delenv(var, raising=False)
    with LocalBackend(2) as backend:
        assert backend.map(os.getenv, list(BLAS_THREAD_VARS)) == ["1"] * len(BLAS_THREAD_VARS)


_LAST: list = []  # in each pool worker: a weak reference to the cycle its last job left


class _Cycle:
    def __init__(self):
        self.me = self


def _leave_a_cycle(_: int) -> tuple[bool | None, bool]:
    """Whether the cycle this worker's previous job left is gone, and whether the worker froze
    its long-lived objects; then leave a new cycle."""
    import gc
    import weakref
    freed = None if not _LAST else _LAST[-1]() is None
    _LAST.append(weakref.ref(_Cycle()))
    return freed, gc.get_freeze_count() > 0


def test_pool_workers_collect_each_job_s_cycles():
    """A frame leaves objects in reference cycles, which the workers' raised collection thresholds
    left for a full collection hundreds of frames away (memory grew through long runs)."""
    with LocalBackend(2) as backend:
        seen = backend.map(_leave_a_cycle, list(range(12)))
    firsts = [f is None for f, _ in seen]  # each worker's first job
    assert 1 <= sum(firsts) <= 2 and all(f for f, _ in seen if f is not None)
    assert [not frozen for _, frozen in seen] == firsts

def _ev(ap3d_mod: float) -> dict:
    block = {"3d": {"R40": [90.0, ap3d_mod, 50.0], "R11": [91.0, 80.0, 51.0]}}
    measured = {"3d": [100.0, ap3d_mod + 20, 95.0]}
    return {"ap": {"Car": block}, "ap_loose": {"Car": block}, "n_gt": {"Car": [3, 5, 6]},
            "ap_r40_measured_recall": {"Car": {"strict": measured, "loose": measured}},
            "range_bins": {"bins": [{"range": [0, 20], "n_gt": {"Car": [1, 2, 2]}, "ap": {"Car": block},
                                     "ap_r40_measured": {"Car": measured}},
                                    {"range": [20, math.inf], "n_gt": {"Car": [0, 0, 0]},
                                     "ap": {"Car": block}, "ap_r40_measured": {"Car": measured}}]}}


def test_report_rows_and_tables():
    p64 = Point("scene", ScanConfig("hdl64e", 64, "native", None), "fit", "gt")
    pmono = Point("scene", None, "mono", "gt")
    rows = metric_rows([(p64, _ev(70.0)), (pmono, _ev(30.0))])
    overall = [r for r in rows if r["range_m"] == "all" and r["iou"] == "strict"]
    assert {(r["method"], r["difficulty"], r["ap_r40"]) for r in overall} >= {
        ("fit", "moderate", "70.0000"), ("mono", "moderate", "30.0000")}
    assert {r["range_m"] for r in rows} == {"all", "0-20", "20+"}
    table = summary_table(rows, "Car", "3d")
    assert "| gt | fit | hdl64e 64 beams | 90.00 | 70.00 | 50.00 | 3 / 5 / 6 |" in table
    assert "| gt | mono | no LiDAR | 90.00 | 30.00 | 50.00 | 3 / 5 / 6 |" in table
    assert {(r["method"], r["difficulty"], r["ap_r40_measured"]) for r in overall} >= {
        ("fit", "moderate", "90.0000"), ("mono", "moderate", "50.0000")}
    # by distance: the measured recall's AP (its bins hold few cars); a bin without truth shows '-'
    table = range_table(rows, "Car", "3d", "gt")
    assert "| | truth boxes | 2 | 0 |" in table
    assert "| fit | hdl64e 64 beams | 90.0 | - |" in table


def test_weather_axis_rescans_the_same_worlds_per_weather(tmp_path):
    spec = load_sweep(_write(tmp_path, """
name: s
scenes: [{spec: scene.yaml}]
axes: {beams: [16], beam_mode: [dropped], weather: [null, {fog_extinction: 0.03}, {rain_rate: 10}]}
"""))
    keys = [s.key for s in plan(spec).scans]
    assert keys == ["hdl64e-64b-native-max-rain10", "hdl64e-64b-native-max-fog0.03",
                    "hdl64e-64b-native-max", "hdl64e-16b-dropped-max", "hdl64e-16b-dropped-max-fog0.03",
                    "hdl64e-16b-dropped-max-rain10"]


def test_cached_results_are_keyed_by_the_lifter_code(tmp_path, monkeypatch):
    """A change to the lifter's code gives a new cache key: stale lifted boxes are never reused."""
    import lifter
    from testbed.sweep import models_key
    pkg = tmp_path / "lifter"
    pkg.mkdir()
    for f in Path(lifter.__file__).parent.glob("*.py"):
        (pkg / f.name).write_bytes(f.read_bytes())
    monkeypatch.setattr(lifter, "__file__", str(pkg / "__init__.py"))
    before = models_key()
    assert models_key() == before
    (pkg / "fit.py").write_text((pkg / "fit.py").read_text() + "\n# changed\n")
    assert models_key() != before


def test_cached_frames_are_keyed_by_the_generator_code(tmp_path, monkeypatch):
    """A change to the scene generator's code, in a subpackage too, gives new frame and scan
    folders: a run or sweep never reuses frames an older generator made."""
    import simgen
    from testbed.sweep import generator_key
    src = Path(simgen.__file__).parent
    pkg = tmp_path / "simgen"
    for f in src.rglob("*.py"):
        (pkg / f.relative_to(src)).parent.mkdir(parents=True, exist_ok=True)
        (pkg / f.relative_to(src)).write_bytes(f.read_bytes())
    monkeypatch.setattr(simgen, "__file__", str(pkg / "__init__.py"))
    before = generator_key()
    assert generator_key() == before
    (pkg / "lidar" / "scan.py").write_text((pkg / "lidar" / "scan.py").read_text() + "\n# changed\n")
    assert generator_key() != before
