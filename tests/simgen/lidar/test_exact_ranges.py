"""A LiDAR hit's range and normal do not depend on the kernels Embree picks: Embree's own distance divides
by an approximate reciprocal whose last bits differ between instruction sets (and between Intel
and AMD CPUs of one set); kernels.exact_hits recomputes it from the hit triangle's plane."""

import numpy as np
from simgen.embree import embree_scene
from simgen.lidar.kernels import exact_hits, triangle_planes


def _street(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """400 randomly tilted triangles 2-60 m from the origin, as float32 vertices and faces."""
    centres = rng.normal(size=(400, 3))
    centres *= rng.uniform(2.0, 60.0, (400, 1)) / np.linalg.norm(centres, axis=1, keepdims=True)
    v = (centres[:, None, :] + rng.normal(scale=1.5, size=(400, 3, 3))).reshape(-1, 3).astype(np.float32)
    return v, np.arange(len(v), dtype=np.int32).reshape(-1, 3)


def _rays(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return rng.normal(scale=0.3, size=(n, 3)).astype(np.float32), d.astype(np.float32)


def _hits(config: bytes, v, f, o, d) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    res = embree_scene(v, f, config).run(o, d, dists=200.0, output=1)
    raw = np.concatenate([res["tfar"][:, None], res["Ng"]], axis=1)
    exact_hits(res["primID"], res["tfar"], res["Ng"], o, d, triangle_planes(v, f)[0])
    return res["primID"], raw, np.concatenate([res["tfar"][:, None], res["Ng"]], axis=1)


def test_ranges_and_normals_are_the_same_bits_whichever_kernels_embree_runs():
    rng = np.random.default_rng(3)
    v, f = _street(rng)
    o, d = _rays(200_000, rng)
    prim, raw, exact = _hits(b"max_isa=avx2", v, f, o, d)
    hit = prim >= 0
    assert hit.sum() > 20_000
    moved = 0
    for config in (b"max_isa=sse2", b"max_isa=avx"):  # every x86-64 CPU runs these
        prim_k, raw_k, exact_k = _hits(config, v, f, o, d)
        assert np.array_equal(prim_k, prim)
        assert exact_k.tobytes() == exact.tobytes()
        moved += int((raw_k[hit] != raw[hit]).any(axis=1).sum())
    assert moved > 0  # Embree's own ranges and normals do move with its kernels: the test bites


def test_ranges_are_the_plane_distance_rounded_to_float32():
    rng = np.random.default_rng(4)
    v, f = _street(rng)
    o, d = _rays(50_000, rng)
    prim, _, got = _hits(b"max_isa=avx2", v, f, o, d)
    t = got[:, 0]
    hit = prim >= 0
    tri = v[f[prim[hit]]].astype(np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    want = np.einsum("ij,ij->i", tri[:, 0] - o[hit], n) / np.einsum("ij,ij->i", d[hit].astype(np.float64), n)
    assert np.all(np.abs(t[hit] - want) <= 2.0 ** -24 * want + 1e-12)  # want rounded to float32
