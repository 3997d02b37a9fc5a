"""Procedural and user meshes: closed parts, exact extents, KITTI-like size statistics."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from simgen.meshes import SIZE_STATS, build_actor_parts, sample_recipe
from simgen.usermesh import user_recipe


@pytest.mark.parametrize("cls", ["Car", "Van", "Truck", "Bus", "Pedestrian", "Cyclist"])
def test_every_part_is_closed_and_the_extent_is_the_drawn_size(cls):
    rng = np.random.default_rng(1)
    for _ in range(5):
        recipe = sample_recipe(cls, rng)
        parts = build_actor_parts(recipe)
        assert all(p.mesh.is_watertight and p.mesh.is_volume for p in parts)
        v = np.concatenate([p.mesh.vertices for p in parts])
        h, w, l = recipe["dims"]
        np.testing.assert_allclose(v.min(axis=0), [-l / 2, -w / 2, 0.0], atol=1e-12)
        np.testing.assert_allclose(v.max(axis=0), [l / 2, w / 2, h], atol=1e-12)
        # Rebuilding from the recipe gives the same vertices, bit for bit.
        again = build_actor_parts(recipe)
        assert all(np.array_equal(a.mesh.vertices, b.mesh.vertices) for a, b in zip(parts, again))


def test_vehicle_parts_have_distinct_lidar_materials():
    parts = build_actor_parts(sample_recipe("Car", np.random.default_rng(0)))
    refl = {p.material.name: p.material.reflectivity for p in parts}
    assert {"paint", "glass", "tyre", "plate", "headlight", "taillight"} <= set(refl)
    assert refl["plate"] > refl["paint"] > refl["glass"] > refl["tyre"]


@pytest.mark.parametrize("cls", ["Car", "Pedestrian", "Cyclist"])
def test_size_distribution_is_close_to_kitti(cls):
    rng = np.random.default_rng(2)
    dims = np.array([sample_recipe(cls, rng)["dims"] for _ in range(400)])
    mean, sd = (np.array(v) for v in SIZE_STATS[cls])
    np.testing.assert_allclose(dims.mean(axis=0), mean, atol=0.25 * sd.max())
    assert np.all(dims.std(axis=0) < 1.2 * sd) and np.all(dims.std(axis=0) > 0.5 * sd)


def test_user_mesh_is_scaled_to_its_target_size(tmp_path):
    path = tmp_path / "blob.ply"
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    m.apply_scale([2.0, 1.0, 0.5])
    m.export(path)
    recipe = user_recipe(str(path), "Car", (1.5, 1.8, 4.2), "z", (0.2, 0.3, 0.4), 0.5)
    (part,) = build_actor_parts(recipe)
    np.testing.assert_allclose(part.mesh.bounds, [[-2.1, -0.9, 0.0], [2.1, 0.9, 1.5]], atol=1e-12)
    own = build_actor_parts(user_recipe(str(path), "Car", None, "z", (0.2, 0.3, 0.4), 0.5))[0]
    np.testing.assert_allclose(own.mesh.bounds[1] - own.mesh.bounds[0], [4.0, 2.0, 1.0], atol=1e-12)
    assert part.material.reflectivity == 0.5
