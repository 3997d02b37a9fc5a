"""build_target's batched shortcuts give the bits of the per-part numpy code they replace."""

import numpy as np

from simgen.lidar.kernels import triangle_planes
from simgen.lidar.target import _placed


def test_placed_matches_per_part_products():
    rng = np.random.default_rng(0)
    poses = []
    for _ in range(5):
        pose = np.eye(4)
        pose[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        pose[:3, 3] = rng.normal(size=3) * 50
        poses.append(pose)
    verts = [rng.normal(size=(n, 3)) * 20 for n in rng.choice([1, 8, 16, 24, 42, 300], 200)]
    pose_of = [None if k % 7 == 0 else int(rng.integers(5)) for k in range(len(verts))]
    for v, j, out in zip(verts, pose_of, _placed(verts, poses, pose_of)):
        want = v if j is None else v @ poses[j][:3, :3].T + poses[j][:3, 3]
        assert np.array_equal(out, want)


def test_triangle_planes_match_numpy():
    rng = np.random.default_rng(1)
    v = (rng.normal(size=(5000, 3)) * np.array([1.0, 30.0, 1e-3])).astype(np.float32)
    f = rng.integers(0, len(v), (20000, 3)).astype(np.int32)
    f[:50, 1] = f[:50, 0]  # degenerate triangles
    tri = v[f].astype(np.float64)
    ng = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    want = (1.0 / np.maximum(ng, 1e-30)).astype(np.float32)
    plane, inv = triangle_planes(v, f)
    assert inv.tobytes() == want.tobytes()
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert plane[:, :3].tobytes() == n.tobytes()
    assert np.allclose(plane[:, 3], np.einsum("ij,ij->i", n, tri[:, 0]), rtol=1e-12, atol=1e-9)
