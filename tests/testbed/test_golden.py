"""End to end on the golden street with exact truth: bounds that must hold, numbers that must not move,
and the same sweep on the local and the Ray backend giving the same files."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from kitti.splits import read_split
from testbed.backends import LocalBackend, RayBackend
from testbed.golden import EXPECTED, ap_tolerance, compute, differences, outcomes
from testbed.sweep import execute, load_sweep, plan

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def golden_run(tmp_path_factory) -> tuple[Path, dict]:
    root = tmp_path_factory.mktemp("golden")
    return root, compute(root, workers=2)


@pytest.fixture(scope="module")
def golden(golden_run) -> dict:
    return golden_run[1]


def test_golden_bounds(golden):
    fit64, fit16 = golden["hdl64e-64b-native-max/fit-gt"], golden["uniform-16b-native-max/fit-gt"]
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


def test_one_lifted_car_moved_by_a_centimetre_is_caught(golden_run):
    """What a one-line change to the lifter does to one car: its box in one frame's result file
    moves 1 cm sideways. Only that Car is named; the AP tier lets it through (one car's
    centimetre is no flip), the per-object tier does not."""
    root, golden = golden_run
    point = "hdl64e-64b-native-max/fit-gt"
    pred = next(root.rglob(f"{point}/pred"))
    data = next(p for p in root.rglob("hdl64e-64b-native-max") if (p / "training").is_dir())
    moved = root / "moved"
    shutil.copytree(pred, moved)
    fid, line, target = next(r.split()[:3] for r in golden[point]["objects"] if r.split()[2] != "-1")
    rows = (moved / f"{fid}.txt").read_text().splitlines()
    fields = rows[int(target)].split()
    fields[11] = f"{float(fields[11]) + 0.01:.2f}"  # location x
    rows[int(target)] = " ".join(fields)
    (moved / f"{fid}.txt").write_text("\n".join(rows) + "\n")
    ids = read_split(data / "ImageSets" / "val.txt")
    changed = {**golden, point: {**golden[point], "objects": outcomes(data / "training" / "label_2", moved, ids)}}
    assert outcomes(data / "training" / "label_2", pred, ids) == golden[point]["objects"]
    found = differences(changed, golden)
    assert len(found) >= 1 and all(f.startswith(f"{point} frame {fid} Car on label line {line}:") for f in found)
    assert len(found) == 1 and "dx " in found[0]


def test_differences_name_what_moved_beyond_its_tolerance():
    point = {"objects": ["000001 0 2 0.8000 0.1000 0.0 0.0500 0.0 0.0 0.0 1.000", "000001 3 -1 0" + " 0" * 7],
             "n_gt": [10, 20, 25], "n_gt_moderate_by_range": {"0": 5, "20": 0}, "matched": 12,
             "3d_r40": [80.0, 70.0, 60.0], "bev_r40": [80.0, 70.0, 60.0], "3d_loose_r40": [80.0, 70.0, 60.0],
             "3d_r40_moderate_by_range": {"0": 75.0, "20": None},
             "centre_median": 0.20, "depth_median": 0.1, "yaw_deg_median": 1.0}
    want = {"p": point}
    assert differences(want, want) == []
    assert ap_tolerance(20) == 2.5 and ap_tolerance(0) == 0.0
    # AP within 50/N points passes (N = 20 moderate: 2.5), beyond does not; a count exactly;
    # None against a number moves; each Car's outcome within its tolerance
    got = {"p": {**point, "3d_r40": [84.9, 67.4, 60.0], "matched": 11,
                 "3d_r40_moderate_by_range": {"0": 75.0, "20": 3.0},
                 "objects": ["000001 0 2 0.8000 0.1050 0.0 0.0500 0.0 0.0 0.0 1.000",
                             "000001 3 4 0.1 0.5 0.2 3.0 0 0 0 0"]}}
    assert differences(got, want) == [
        "p frame 000001 Car on label line 0: dx 0.1050 != 0.1000",
        "p frame 000001 Car on label line 3: lifted Car 4, expected -1",
        "p.matched: 11 != 12",
        "p.3d_r40[1]: 67.4000 != 70.0000 (tolerance 2.5)",
        "p.3d_r40_moderate_by_range.20: 3.0 != None"]
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
