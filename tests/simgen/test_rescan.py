"""A sweep's rescans of one dataset: one job per frame serves every scan configuration, builds the
world's Embree scene once, and writes exactly the files of separate single rescans."""

from __future__ import annotations

import pytest

import simgen.lidar.target as target_module
from kitti.jobs import InProcess
from simgen.rescan import RescanRequest, WeatherOverride, rescan
from simgen.spec import LidarSection
from testbed import stages

FRAMES = 2
REQUESTS = {
    "vlp16": RescanRequest(LidarSection(preset="vlp16")),
    "hdl64e-16b-fog": RescanRequest(LidarSection(preset="hdl64e", beams=16),
                                    WeatherOverride(fog_extinction=0.03)),
    "uniform-32b-50m": RescanRequest(LidarSection(preset="uniform", beams=32, max_range=50.0)),
}


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    from simgen.generate import generate
    from simgen.spec import load_spec

    root = tmp_path_factory.mktemp("rescan_src")
    generate(load_spec("scenes/quickstart.yaml"), root, frames=FRAMES)
    return root


@pytest.fixture
def scene_builds(monkeypatch):
    """How many Embree scenes the LiDAR builds (the builder build_target calls)."""
    calls = []
    builder = target_module.embree_scene

    def counted(*args, **kwargs):
        calls.append(1)
        return builder(*args, **kwargs)

    monkeypatch.setattr(target_module, "embree_scene", counted)
    return calls


def _files(root):
    return {p.relative_to(root): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != ".done"}


def test_one_job_per_frame_scans_every_request_with_one_scene(source, tmp_path, scene_builds):
    for name, request in REQUESTS.items():
        rescan(source, tmp_path / "single" / name, request)
    assert len(scene_builds) == FRAMES * len(REQUESTS)  # one scene per frame and request

    scene_builds.clear()
    scans = [stages.Rescan(source, tmp_path / "batch" / name, r) for name, r in REQUESTS.items()]
    stages.rescan(scans, InProcess())
    assert len(scene_builds) == FRAMES
    for name in REQUESTS:
        single, batch = _files(tmp_path / "single" / name), _files(tmp_path / "batch" / name)
        assert single.keys() == batch.keys() and len(single) > 0
        assert [k for k in single if single[k] != batch[k]] == [], name

    # done: nothing is rebuilt; one request's frame gone: only that frame is scanned again
    scene_builds.clear()
    stages.rescan(scans, InProcess())
    assert scene_builds == []
    (tmp_path / "batch" / "vlp16" / ".done").unlink()
    (tmp_path / "batch" / "vlp16" / "training" / "meta" / "000001.json").unlink()
    stages.rescan(scans, InProcess())
    assert len(scene_builds) == 1
    assert _files(tmp_path / "batch" / "vlp16") == _files(tmp_path / "single" / "vlp16")
