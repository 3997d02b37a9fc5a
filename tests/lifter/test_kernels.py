"""The lifter's numba kernels against plain numpy references on random input: each kernel replaced
numpy code of the same arithmetic, so they agree to round-off (the selections exactly)."""

import numpy as np
import pytest

from kitti.boxes import UNIT_CORNERS, box_corners, project_boxes, wrap_angle
from kitti.calib import Calibration
from lifter import fit, ground, mono, road
from lifter.mono import box_up_of
from lifter.placement import CAMERA_UP, length_from_sides, side_cost, translation

CALIB = Calibration.kitti_default()
P = CALIB.P(2)
SIZE = (1242, 375)
TIGHT = {"rtol": 1e-12, "atol": 1e-12}


def _percentile(v, q):
    k = round(q / 100.0 * (len(v) - 1))
    return np.partition(v, k)[k]


def _plane(rng):
    """A road plane tilted a few degrees, unit normal up, 1.5-1.8 m below the camera."""
    n = np.array([rng.normal(0, 0.05), -1.0, rng.normal(0, 0.05)])
    n /= np.linalg.norm(n)
    return np.append(n, rng.uniform(1.5, 1.8))


def _scan(rng, n=3000):
    """Returns spread in front of the camera (rect frame) and their pixels."""
    rect = np.column_stack([rng.uniform(-15, 15, n), rng.uniform(-1.0, 2.0, n),
                            rng.uniform(3, 60, n)])
    return rect, CALIB.rect_to_image(rect)[0]


def _car_returns(rng, n):
    """Noisy returns on the two faces of a car the sensor sees, their columns and heights, and
    the car's box and 2D box."""
    car = np.array([rng.uniform(-6, 6), 1.65, rng.uniform(8, 35), rng.uniform(1.4, 1.7),
                    rng.uniform(1.6, 1.9), rng.uniform(3.8, 4.8), rng.uniform(-np.pi, np.pi)])
    foot = box_corners(car[None])[0][:4][:, [0, 2]]
    k = np.argmin(np.linalg.norm(foot, axis=1))  # the corner nearest the camera: both its faces
    t = rng.uniform(0, 1, n)[:, None]
    side = rng.integers(0, 2, n)[:, None]
    ends = np.where(side == 0, foot[(k + 1) % 4], foot[(k + 3) % 4])
    xz = foot[k] + t * (ends - foot[k]) + rng.normal(0, 0.01, (n, 2))
    height = rng.uniform(0.2, car[3] * rng.uniform(0.5, 1.0), n)  # the roof hit or not
    u = CALIB.rect_to_image(np.column_stack([xz[:, 0], car[1] - height, xz[:, 1]]))[0][:, 0]
    return xz, u, height, car, project_boxes(car[None], CALIB, SIZE)[0]


# --- fit ------------------------------------------------------------------------------------

def test_frustum_returns_are_the_masked_pool():
    rng = np.random.default_rng(0)
    rect, uv = _scan(rng)
    pool = np.sort(rng.choice(len(rect), 2000, replace=False))
    free = rng.uniform(size=len(rect)) > 0.2
    plane = _plane(rng)
    width = 1242.0
    for bbox in ([300.0, 100.0, 700.0, 300.0], [0.0, 0.0, 1241.0, 374.0], [10.0, 10.0, 11.0, 11.0],
                 [-np.inf, 150.0, 200.0, 300.0]):  # the last opened at the left border
        bbox = np.array(bbox)
        u, v = uv[pool, 0], uv[pool, 1]
        rows = ((v >= bbox[1]) & (v <= bbox[3])) | (u < 0) | (u > width)  # no row test past the border
        cand = pool[(u >= bbox[0]) & (u <= bbox[2]) & rows]
        cand = cand[free[cand]]
        hl = rect[cand] @ plane[:3] + plane[3]
        keep = (hl > fit.ROAD_CUT) & (hl < fit.MAX_HEIGHT)
        idx, h = fit._frustum_returns(rect, uv, pool, uv[pool, 0], free, bbox, plane, width)
        np.testing.assert_array_equal(idx, cand[keep])
        np.testing.assert_allclose(h, hl[keep], **TIGHT)


def test_bev_and_claims_match_numpy():
    rng = np.random.default_rng(1)
    rect, uv = _scan(rng)
    idx = np.sort(rng.choice(len(rect), 500, replace=False))
    sensor = np.array([0.27, -0.08])
    xz, u, rng_m = fit._bev(rect, uv, idx, sensor)
    np.testing.assert_array_equal(xz, rect[idx][:, [0, 2]])
    np.testing.assert_array_equal(u, uv[idx, 0])
    np.testing.assert_allclose(rng_m, np.linalg.norm(xz - sensor, axis=1), **TIGHT)
    b = np.array([1.0, 1.6, 20.0, 1.5, 6.0, 12.0, 0.7])
    d = rect[idx][:, [0, 2]] - b[[0, 2]]
    c, s = np.cos(b[6]), np.sin(b[6])
    inside = (np.abs(d[:, 0] * c - d[:, 1] * s) <= b[5] / 2) & (np.abs(d[:, 0] * s + d[:, 1] * c) <= b[4] / 2)
    assert inside.sum() > 0
    np.testing.assert_array_equal(fit._in_box_bev(rect, idx, b), idx[inside])


def test_closeness_and_wrap_match_numpy():
    rng = np.random.default_rng(2)
    xz = rng.normal(size=(200, 2)) * [2.0, 0.8]
    thetas = rng.uniform(0, np.pi / 2, 40)
    c, s = np.cos(thetas)[:, None], np.sin(thetas)[:, None]
    a, b = c * xz[:, 0] - s * xz[:, 1], s * xz[:, 0] + c * xz[:, 1]
    d = np.minimum(np.minimum(a.max(1, keepdims=True) - a, a - a.min(1, keepdims=True)),
                   np.minimum(b.max(1, keepdims=True) - b, b - b.min(1, keepdims=True)))
    ref = (1.0 / np.maximum(d, fit.LSHAPE_D0)).sum(axis=1)
    np.testing.assert_allclose(fit._closeness(xz, thetas), ref, rtol=1e-12)
    for angle in rng.uniform(-20, 20, 200):
        assert mono.wrap_one(angle) == wrap_angle(angle)


def _rect_rms_ref(xz, ry):
    a = xz @ np.array([np.cos(ry), -np.sin(ry)])
    b = xz @ np.array([np.sin(ry), np.cos(ry)])
    ends = [_percentile(a, 2.0), _percentile(a, 98.0), _percentile(b, 2.0), _percentile(b, 98.0)]
    d = np.min(np.abs(np.stack([a - ends[0], ends[1] - a, b - ends[2], ends[3] - b])), axis=0)
    return np.sqrt(np.mean(d * d))


def _hypotheses_ref(body, ry_prior, small):
    """`fit._best_yaw`'s yaws and their costs before placement, as numpy wrote them."""
    if small or len(body) < fit.MIN_LSHAPE:
        ry = ry_prior
    else:
        theta = fit._lshape_angle(body)
        ry = float(wrap_angle(theta + np.round((ry_prior - theta) / (np.pi / 2)) * np.pi / 2))
    hyps = [(ry, 0.0)]
    if not small:
        perp = ry + np.pi / 2 * np.array([1.0, -1.0, 1.0, -1.0]) + np.array([0, 0, np.pi, np.pi])
        perp = float(wrap_angle(perp[np.argmin(np.abs(wrap_angle(perp - ry_prior)))]))
        hyps = [(ry, float(wrap_angle(2 * (ry - ry_prior)) / 2)), (ry_prior, 0.0),
                (perp, float(wrap_angle(2 * (perp - ry_prior)) / 2))]
        if abs(hyps[0][1]) < fit.SAME_YAW:
            del hyps[1]
    pts = body[:: -(-len(body) // fit.MAX_LSHAPE_POINTS)]
    fits = len(pts) >= fit.MIN_LSHAPE
    rms_best = _rect_rms_ref(pts, ry) if fits else 0.0
    costs = [(off / fit.SIGMA_YAW_PRIOR) ** 2
             + (((_rect_rms_ref(pts, h) - rms_best) / fit.SIGMA_RECT) ** 2 if fits and h != ry else 0.0)
             for h, off in hyps]
    return np.array([h for h, _ in hyps]), np.array(costs)


@pytest.mark.parametrize("n", [5, 60, 700])
@pytest.mark.parametrize("small", [False, True])
def test_yaw_hypotheses_match_numpy(n, small):
    rng = np.random.default_rng(n)
    for _ in range(5):
        xz = _car_returns(rng, n)[0]
        ry_prior = rng.uniform(-np.pi, np.pi)
        yaws, costs = fit._yaw_hypotheses(xz, ry_prior, small)
        ref_yaws, ref_costs = _hypotheses_ref(xz, ry_prior, small)
        np.testing.assert_allclose(yaws, ref_yaws, **TIGHT)
        np.testing.assert_allclose(costs, ref_costs, rtol=1e-9, atol=1e-9)


def test_refine_costs_are_the_scalar_ones_bit_for_bit():
    """Step 3b's batched kernels against `_rect_rms` per yaw and the cost as Python wrote it."""
    rng = np.random.default_rng(12)
    for _ in range(10):
        xz = _car_returns(rng, 300)[0]
        ry_prior = rng.uniform(-np.pi, np.pi)
        yaws = rng.uniform(-np.pi, np.pi, 9)
        rms = fit._rect_rms_each(xz, yaws)
        assert rms.tolist() == [fit._rect_rms(xz, y) for y in yaws.tolist()]
        rms_min = float(rms.min())
        ref = [((mono.wrap_one(2 * (y - ry_prior)) / 2 / fit.SIGMA_YAW_PRIOR) ** 2
                + (max(r - rms_min, 0.0) / fit.SIGMA_RECT) ** 2)
               for y, r in zip(yaws.tolist(), rms.tolist())]
        assert fit._yaw_pre(yaws, rms, ry_prior, rms_min).tolist() == ref


def test_size_and_place_matches_numpy():
    """The kernel against the steps it fuses, as numpy called them (placement's kernels are
    tested on their own in test_placement)."""
    rng = np.random.default_rng(3)
    plane, sensor = np.array([0.0, -1.0, 0.0, 1.65]), np.array([0.27, -0.08])
    for trial in range(20):
        xz, u, height, car, bbox = _car_returns(rng, int(rng.integers(20, 400)))
        h, w, l = car[3:6] + rng.normal(0, 0.2, 3)
        ry, small = car[6] + rng.normal(0, 0.05), trial % 5 == 0
        is_car = trial % 3 != 0
        sigma, dof = (2.0, np.inf) if trial % 2 else (3.6, 1.6)  # a label's sides, a detection's
        centroid = xz.mean(axis=0)
        pa = xz @ np.array([np.cos(ry), -np.sin(ry)])
        pb = xz @ np.array([np.sin(ry), np.cos(ry)])
        ext_a = _percentile(pa, 98.0) - _percentile(pa, 2.0)
        ext_b = _percentile(pb, 98.0) - _percentile(pb, 2.0)
        l_ref, w_ref, h_ref = l, w, h
        if not small:
            l_ref = ext_a if l < ext_a <= l + fit.MAX_GROW_L else l
            w_ref = ext_b if w < ext_b <= w + fit.MAX_GROW_W else w
        if height.max() > fit.ROOF_SEEN * h:
            h_ref = float(np.clip(h, height.max(), height.max() + fit.ROOF_GAP))
        up = CAMERA_UP if trial % 2 else box_up_of("box", CALIB)
        ways = [(np.inf, True)]
        if is_car and not small:  # across the mirrors, across the body, the prior's width
            ways += [(fit.MIRROR_FOOT * h_ref, True), (fit.MIRROR_FOOT * h_ref, False)]
        best = None
        for body_top, measure in ways:
            T, dims, pinned, slide = translation(xz, u, height, h_ref, w_ref, l_ref, ry, bbox,
                                                 sensor, centroid, P, SIZE[0], plane, is_car, up,
                                                 body_top, measure)
            length_cost = 0.0
            if not small and slide.any():
                T, dims[2] = length_from_sides(T, *dims, ry, slide, bbox, P, SIZE[0], plane, up, sigma, dof)
                length_cost = ((dims[2] - l_ref) / fit.SIGMA_LENGTH) ** 2
            misfit = side_cost(np.array([[*T, *dims, ry]]), P, bbox, SIZE[0], up, sigma, dof)[0]
            cost = misfit + length_cost
            if best is None or (dims[1] != best[1][1] and cost < best[5]):
                best = (T, dims, pinned, misfit, length_cost, cost)
        T, dims, pinned, misfit, length_cost, _ = best
        out = fit._size_and_place(xz, u, height, h, w, l, ry, small, is_car, bbox, sensor,
                                  centroid, P, SIZE[0], plane, up, sigma, dof)
        np.testing.assert_allclose(out[0], T, **TIGHT)
        np.testing.assert_allclose(out[1], dims, **TIGHT)
        assert out[2] == pinned
        np.testing.assert_allclose(out[3:], [misfit, length_cost], rtol=1e-9, atol=1e-12)


# --- mono -----------------------------------------------------------------------------------

def _standing_ref(h, w, l, ry, up):
    c, s = np.cos(ry), np.sin(ry)
    head = np.array([c, (up[2] * -s + up[0] * c) / -up[1], -s])
    head /= np.linalg.norm(head)
    side = np.cross(up, head)
    u = UNIT_CORNERS
    return np.outer(u[:, 0] * l, head) - np.outer(u[:, 1] * h, up) + np.outer(u[:, 2] * w, side)


def test_standing_corners_and_pixel_depth_match_numpy():
    rng = np.random.default_rng(4)
    for _ in range(50):
        up = _plane(rng)[:3]
        dims, ry = rng.uniform(1, 5, 3), rng.uniform(-np.pi, np.pi)
        np.testing.assert_allclose(mono.standing_corners(*dims, ry, up),
                                   _standing_ref(*dims, ry, up), **TIGHT)
        uv, z = rng.uniform(0, 1242, 2), rng.uniform(0, 80)
        np.testing.assert_array_equal(mono._pixel_at_depth(P, *uv, z),
                                      CALIB.image_to_rect(uv[None], np.array([z]))[0])


def _assignment_ref(o, offs, feet):
    """`mono._place`'s search as numpy wrote it: the translation and error of the best corner
    assignment."""
    def project(pts):
        hom = np.einsum("...j,ij->...i", pts, P[:, :3]) + P[:, 3]
        return hom[..., :2] / hom[..., 2:3], hom[..., 2]
    W, H = SIZE
    rhs = [-((feet if bottom else offs) @ r[:3] + r[3]) for r, bottom in zip(o.rows, o.on_feet)]
    if len(o.plane_rhs):
        rhs.append(o.plane_rhs)
    combos = o.combos.copy()
    if o.bottom_col >= 0:
        combos[:, o.bottom_col] = int(np.argmax(project(o.ground + feet[:4])[0][:, 1]))
    B = np.stack([rhs[i][combos[:, i]] for i in range(len(rhs))], axis=0)
    T = np.einsum("ij,jk->ki", o.A_pinv, B)
    uv, z = project(T[:, None, :] + offs[None])
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    foot_v = project(T[:, None, :] + feet[None, :4])[0][..., 1].max(axis=1)
    proj = np.stack([np.clip(lo[:, 0], 0, W - 1), np.clip(lo[:, 1], 0, H - 1),
                     np.clip(hi[:, 0], 0, W - 1), np.clip(foot_v, 0, H - 1)], axis=1)
    err = np.where((z > 0.1).all(axis=1), np.abs(proj - o.bbox).mean(axis=1), np.inf)
    return T[np.argmin(err)], err.min()


@pytest.mark.parametrize("with_plane", [True, False])
def test_best_assignment_matches_numpy(with_plane):
    rng = np.random.default_rng(5)
    for _ in range(30):
        plane = _plane(rng) if with_plane else None
        x1, y1 = rng.uniform(-20, 1100), rng.uniform(60, 300)
        bbox = np.array([x1, y1, x1 + rng.uniform(20, 300), min(y1 + rng.uniform(15, 150), 374.0)])
        o = mono._outline(bbox, CALIB, SIZE, plane, 2, cut_ok=True)
        dims, ry = rng.uniform([1.3, 1.5, 3.5], [1.8, 2.0, 5.0]), rng.uniform(-np.pi, np.pi)
        offs = mono.standing_corners(*dims, ry, o.up)
        feet = mono.standing_corners(dims[0], dims[1] * 0.92, dims[2] * 0.64, ry, o.up)
        T, err = mono._best_assignment(o.rows, o.on_feet, o.A_pinv, o.plane_rhs, o.combos,
                                       o.bottom_col, o.ground, offs, feet, P, *SIZE, o.bbox)
        T_ref, err_ref = _assignment_ref(o, offs, feet)
        np.testing.assert_allclose(err, err_ref, rtol=1e-9)
        np.testing.assert_allclose(T, T_ref, rtol=1e-9, atol=1e-9)


def _alpha_ref(dims, alpha, bbox, plane, iters=8, tol=1e-5):
    """`solve_from_alpha` as it was written before its iteration became a kernel: `_place` per
    yaw, numpy's arctan2 and wrap_angle."""
    o = mono._outline(bbox, CALIB, SIZE, plane, 2, cut_ok=True)
    ray = mono._pixel_at_depth(P, 0.5 * (bbox[0] + bbox[2]), 0.5 * (bbox[1] + bbox[3]), 10.0)
    ry = float(wrap_angle(alpha + np.arctan2(ray[0], ray[2])))
    sol = mono._place(o, dims, ry, (1.0, 1.0))
    for _ in range(iters):
        ry_new = float(wrap_angle(alpha + np.arctan2(sol.location[0], sol.location[2])))
        if abs(wrap_angle(ry_new - ry)) < tol:
            break
        ry = ry_new
        sol = mono._place(o, dims, ry, (1.0, 1.0))
    return sol


def test_alpha_iterations_are_the_placements_bit_for_bit():
    rng = np.random.default_rng(9)
    for _ in range(40):
        plane = _plane(rng)
        x1, y1 = rng.uniform(-20, 1100), rng.uniform(60, 300)
        bbox = np.array([x1, y1, x1 + rng.uniform(20, 300), min(y1 + rng.uniform(15, 150), 374.0)])
        dims, alpha = rng.uniform([1.3, 1.5, 3.5], [1.8, 2.0, 5.0]), rng.uniform(-np.pi, np.pi)
        sol = mono.solve_from_alpha(dims, alpha, bbox, CALIB, SIZE, plane, cut_ok=True)
        ref = _alpha_ref(dims, alpha, bbox, plane)
        assert sol.location.tobytes() == ref.location.tobytes()
        assert (sol.rotation_y, sol.box_error_px) == (ref.rotation_y, ref.box_error_px)


def test_outline_is_reused_only_for_the_same_box_and_road():
    rng = np.random.default_rng(10)
    plane = _plane(rng)
    bbox = np.array([500.0, 170.0, 620.0, 240.0])
    o = mono._outline(bbox, CALIB, SIZE, plane, 2, False)
    assert mono._outline(bbox.copy(), CALIB, SIZE, plane.copy(), 2, False) is o
    other_road = plane + np.array([0.0, 0.0, 0.0, 0.05])
    moved = bbox + np.array([0.0, 0.0, 0.0, 1.0])
    for args in ((bbox, other_road, False), (moved, plane, False), (bbox, plane, True),
                 (bbox, None, False)):
        fresh = mono._build_outline(args[0], CALIB, SIZE, args[1], 2, args[2])
        got = mono._outline(args[0], CALIB, SIZE, args[1], 2, args[2])
        assert got is not o
        np.testing.assert_array_equal(got.A_pinv, fresh.A_pinv)
        np.testing.assert_array_equal(got.ground, fresh.ground)


def test_height_from_top_matches_numpy():
    """The kernel against the corners `mono.standing_corners` stands on the same up: the least
    height at which a top corner reaches the row, for the camera's up (the closed form it had
    before, y = max_i y_i) and for ups tilted a few degrees."""
    from lifter.mono import standing_corners
    from lifter.placement import CAMERA_UP, HEIGHT_RANGE, height_from_top
    rng = np.random.default_rng(11)
    for i in range(200):
        T = np.array([rng.uniform(-10, 10), rng.uniform(1.4, 1.9), rng.uniform(5, 60)])
        dims, ry = rng.uniform([1.3, 1.5, 3.5], [1.8, 2.0, 5.0]), rng.uniform(-np.pi, np.pi)
        top = rng.uniform(100, 200)
        h = dims[0]
        up = CAMERA_UP if i % 2 else CAMERA_UP + np.r_[rng.normal(0, 0.05, 1), 0.0, rng.normal(0, 0.05, 1)]
        up = up / np.linalg.norm(up)
        feet = T + standing_corners(1.0, dims[1], dims[2], ry, None if i % 2 else up)[:4]
        r = P[1] - top * P[2]
        h_ref = float(np.min(-(feet @ r[:3] + r[3]) / (r[:3] @ up)))
        if i % 2:  # the camera's up: the closed form in y
            c, s = np.cos(ry), np.sin(ry)
            xz = np.array([[dims[2] / 2, dims[1] / 2], [dims[2] / 2, -dims[1] / 2],
                           [-dims[2] / 2, dims[1] / 2], [-dims[2] / 2, -dims[1] / 2]])
            x, z = T[0] + xz[:, 0] * c + xz[:, 1] * s, T[2] - xz[:, 0] * s + xz[:, 1] * c
            num = top * (P[2, 0] * x + P[2, 2] * z + P[2, 3]) - (P[1, 0] * x + P[1, 2] * z + P[1, 3])
            assert h_ref == pytest.approx(T[1] - float(np.max(num / (P[1, 1] - top * P[2, 1]))), abs=1e-9)
        h_ref = h_ref if HEIGHT_RANGE[0] * h <= h_ref <= HEIGHT_RANGE[1] * h else h
        assert height_from_top(T, dims, ry, top, P, up) == pytest.approx(h_ref, abs=1e-9)


# --- ground and road ------------------------------------------------------------------------

def test_ground_kernels_match_numpy():
    rng = np.random.default_rng(6)
    pts = np.column_stack([rng.uniform(-20, 20, 3000), 1.65 + rng.normal(0, 0.05, 3000),
                           rng.uniform(2, 60, 3000)])
    n = rng.normal(size=(60, 3)) * [0.05, 1.0, 0.05]
    n /= np.linalg.norm(n, axis=1)[:, None]
    d = rng.uniform(1.55, 1.75, 60) * -np.sign(n[:, 1])
    ref = (np.abs(pts @ n.T + d) < ground.INLIER_M).sum(axis=0)
    np.testing.assert_array_equal(ground._inlier_counts(pts, n, d, ground.INLIER_M), ref)
    plane = np.array([0.001, -1.0, 0.002, 1.65]) / np.linalg.norm([0.001, -1.0, 0.002])
    inliers = pts[np.abs(ground.height_above(pts, plane)) < ground.INLIER_M]
    q = inliers - inliers.mean(axis=0)
    count, centre, scatter = ground._inlier_scatter(pts, plane, ground.INLIER_M)
    assert count == len(inliers) > 100
    np.testing.assert_allclose(centre, inliers.mean(axis=0), **TIGHT)
    np.testing.assert_allclose(scatter, q.T @ q, rtol=1e-10)


def test_ray_depth_matches_numpy():
    rng = np.random.default_rng(7)
    c = road.camera_rays(P, np.zeros((1, 2)))[0]
    for _ in range(200):
        d, plane = rng.normal(size=3), _plane(rng)
        rate = plane[:3] @ d
        x = c + (-(plane[:3] @ c + plane[3]) / rate) * d
        ref = 200.0 if rate >= -1e-9 else min(float(np.hypot(x[0], x[2])), 200.0)
        np.testing.assert_allclose(road.ray_depth(c, d, plane), ref, **TIGHT)
