"""End to end on the golden street with exact truth: bounds that must hold, numbers that must not move,
and the same sweep on the local and the Ray backend giving the same files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from testbed.backends import LocalBackend, RayBackend
from testbed.golden import EXPECTED, compute, differences
from testbed.sweep import execute, load_sweep, plan

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def golden(tmp_path_factory) -> dict:
    return compute(tmp_path_factory.mktemp("golden"), workers=2)


def test_golden_bounds(golden):
    fit64, fit16 = golden["hdl64e-64b-native-max/fit-gt"], golden["hdl64e-16b-native-max/fit-gt"]
    mono = golden["no-lidar/mono-gt"]
    # oracle boxes, 64 beams, noise as in the sensor: the fitted boxes overlap the truth
    assert fit64["3d_loose_r40"][1] >= 60.0
    assert fit64["centre_median"] < 0.3
    # fewer beams never help
    assert fit16["3d_r40"][1] <= fit64["3d_r40"][1] + 1e-6
    assert fit16["bev_r40"][1] <= fit64["bev_r40"][1] + 1e-6
    # the image alone is less accurate than the LiDAR at short range
    assert mono["centre_median"] > fit64["centre_median"]
    assert mono["3d_r40_moderate_by_range"]["0"] <= fit64["3d_r40_moderate_by_range"]["0"]


def test_golden_numbers_match_the_committed_expectation(golden):
    """If this fails after an intended change: `.venv/bin/python -m testbed.golden --update`."""
    assert differences(golden, json.loads(EXPECTED.read_text())) == []


def test_differences_name_what_moved_beyond_its_tolerance():
    want = {"p": {"3d_r40": [80.0, 70.0, 60.0], "3d_r40_moderate_by_range": {"0": 75.0, "20": None},
                  "matched": 12, "centre_median": 0.20}}
    got = {"p": {"3d_r40": [80.5, 69.4, 60.0], "3d_r40_moderate_by_range": {"0": 75.0, "20": 3.0},
                 "matched": 11, "centre_median": 0.209}}
    assert differences(want, want) == []
    # AP within 0.5 points passes, 0.6 does not; None against a number moves; the count exactly;
    # errors within 0.01
    assert differences(got, want) == ["p.3d_r40[1]: 69.4 != 70.0 (tolerance 0.5)",
                                      "p.3d_r40_moderate_by_range.20: 3.0 != None",
                                      "p.matched: 11 != 12 (tolerance 0.0)"]
    assert differences({}, want) == ["p: not computed"]
    assert differences({**want, "q": {}}, want) == ["q: not in the expectation"]


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != ".done"}


def test_two_point_sweep_is_identical_on_local_and_ray(tmp_path):
    ray = pytest.importorskip("ray")
    spec = load_sweep(ROOT / "scenes" / "sweeps" / "two_point.yaml")
    local = plan(spec, tmp_path / "local")
    with LocalBackend(2) as backend:
        execute(local, backend)
    try:
        remote = plan(spec, tmp_path / "ray")
        execute(remote, RayBackend(workers=2))
    finally:
        ray.shutdown()
    a, b = _files(local.root), _files(remote.root)
    assert len(a) > 20 and a.keys() == b.keys()
    assert [k for k in a if a[k] != b[k]] == []
