"""Scene specs: every error names the key and the file; factors sample as documented."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simgen.factors import factor_rng
from simgen.sample import _values, sample_world
from simgen.spec import SpecError, load_spec, spec_from_dict, spec_to_dict

SCENES = sorted(Path(__file__).resolve().parents[2].glob("scenes/*.yaml"))


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.name)
def test_shipped_specs_load_and_round_trip(path):
    spec = load_spec(path)
    assert spec_from_dict(spec_to_dict(spec)) == spec


def test_required_scenes_are_shipped():
    names = {p.name for p in SCENES}
    assert {"quickstart.yaml", "urban.yaml", "highway.yaml", "roadside_gantry.yaml",
            "variations.yaml"} <= names


@pytest.mark.parametrize("text,key,words", [
    ("name: x\nroad: {lanez: 2}\n", "road.lanez", "Extra inputs"),
    ("name: x\nroad: {lane_width: wide}\n", "road.lane_width", "expected a number"),
    ("name: x\nroad: {lanes_per_direction: 7}\n", "road.lanes_per_direction", "above the maximum 4"),
    ("name: x\nweather: {fog_extinction: {range: [0.05, 0.01]}}\n", "weather.fog_extinction", "lo > hi"),
    ("name: x\nlight: {time: noon}\n", "light.time", "not one of"),
    ("name: x\nsensor: {rang: [1, 2]}\n", "sensor", "unknown factor form"),
    ("name: x\ntraffic: {mix: {Bike: 1.0}}\n", "traffic.mix", "unknown vehicle class"),
    ("name: x\nframes: 0\n", "frames", "greater than or equal to 1"),
    ("road: {}\n", "name", "Field required"),
])
def test_spec_errors_name_the_key_and_the_file(tmp_path, text, key, words):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(SpecError) as e:
        load_spec(path)
    msg = str(e.value)
    assert str(path) in msg and f"'{key}" in msg and words in msg, msg


def test_yaml_syntax_error_names_the_file(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: [x\n")
    with pytest.raises(SpecError, match="broken.yaml: not valid YAML"):
        load_spec(path)


def test_missing_user_mesh_names_the_key(tmp_path):
    path = tmp_path / "u.yaml"
    path.write_text("name: u\nuser_meshes: [{path: nope.obj, cls: Car}]\n")
    with pytest.raises(SpecError, match=r"user_meshes\.0\.path.*no such file"):
        load_spec(path)


def test_factor_forms_sample_their_documented_values():
    spec = spec_from_dict({"name": "f", "light": {
        "sun_elevation_deg": {"steps": [5, 90, 3]}, "sun_azimuth_deg": {"range": [10, 20]},
        "time": {"choice": ["day", "night"]}, "sun_intensity": 0.5}})
    seen = {"el": set(), "time": set()}
    for frame in range(60):
        v = _values(spec, 11, frame)
        seen["el"].add(v["light.sun_elevation_deg"])
        seen["time"].add(v["light.time"])
        assert 10 <= v["light.sun_azimuth_deg"] <= 20
        assert v["light.sun_intensity"] == 0.5
    assert seen["el"] == {5.0, 47.5, 90.0}
    assert seen["time"] == {"day", "night"}


def test_fixing_one_factor_leaves_the_others_draws_unchanged():
    a = spec_from_dict({"name": "a", "light": {"sun_intensity": {"range": [0.1, 1.0]},
                                               "sun_elevation_deg": {"range": [5, 90]}}})
    b = spec_from_dict({"name": "a", "light": {"sun_intensity": 0.3,
                                               "sun_elevation_deg": {"range": [5, 90]}}})
    for frame in range(5):
        assert _values(a, 3, frame)["light.sun_elevation_deg"] == _values(b, 3, frame)["light.sun_elevation_deg"]
    assert factor_rng(3, 0, "x").uniform() != factor_rng(3, 1, "x").uniform()


def test_sampled_worlds_are_deterministic_and_collision_free():
    from simgen.relief import TILTED
    from simgen.road import RoadLayout
    from simgen.sample import EGO_FOOTPRINT, _footprint

    spec = load_spec(Path(__file__).resolve().parents[2] / "scenes/urban.yaml")
    w1, w2 = sample_world(spec, 5, 5), sample_world(spec, 5, 5)  # parked rows along both kerbs
    assert len(w1.actors) == len(w2.actors) > 40
    for a, b in zip(w1.actors, w2.actors):
        assert a.recipe == b.recipe and np.array_equal(a.pose, b.pose)
    fps = [_footprint(a.pose, a.recipe["dims"][2], a.recipe["dims"][1], 0.0) for a in w1.actors]
    for i, f in enumerate(fps):
        assert not f.intersects(EGO_FOOTPRINT)
        for g in fps[i + 1:]:
            assert f.intersection(g).area == 0.0
    road = RoadLayout(**w1.scenery["road"])
    assert road.profile is not None  # urban.yaml's roads rise and fall
    for a in w1.actors:  # on the road or on the sidewalk; vehicles tilted with the road
        x, y, z = a.pose[:3, 3]
        above = z - float(road.height(x, y))
        assert min(abs(above), abs(above - road.curb_height)) < 1e-9
        up = road.surface_normal(x, y) if a.cls in TILTED else [0.0, 0.0, 1.0]
        np.testing.assert_allclose(a.pose[:3, 2], up, atol=1e-12)
    assert max(a.pose[0, 3] for a in w1.actors) > 100.0  # traffic out beyond 100 m


def test_intersection_keeps_its_cross_street_clear():
    import shapely

    from simgen.road import RoadLayout
    from simgen.scenery import build_scenery

    spec = spec_from_dict({"name": "i", "road": {"type": "intersection", "intersection_distance": 30,
                                                 "cross_lanes_per_direction": 2},
                           "traffic": {"vehicles_per_100m": 5, "pedestrians_per_100m": 20}})
    world = sample_world(spec, 2, 0)
    road = RoadLayout(**world.scenery["road"])
    assert road.cross_s == 30.0 and road.curvature == 0.0
    crossing = [a for a in world.actors  # vehicles heading along +-y
                if a.cls in ("Car", "Van", "Truck") and abs(a.pose[1, 0]) > 0.9]
    assert len(crossing) >= 2
    for a in crossing:
        assert abs(a.pose[0, 3] - 30.0) < road.cross_half_width
    walkers = [a for a in world.actors if a.cls == "Pedestrian"]
    assert len(walkers) >= 5
    for a in walkers:
        assert not road.in_cross_street(a.pose[0, 3])
    band = shapely.box(30.0 - road.cross_half_width, -100, 30.0 + road.cross_half_width, 100)
    _, obstacles = build_scenery(world.scenery)
    assert obstacles and not any(o.polygon.intersects(band) for o in obstacles)
