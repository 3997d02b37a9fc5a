"""The LiDAR box fit on exact synthetic scans: centre and yaw of unoccluded cars, sparse beams,
the road plane, the image-only fallback."""

import numpy as np
import pytest

from kitti.boxes import box_corners, project_boxes, wrap_angle
from kitti.calib import Calibration
from kitti.iou import iou_2d, iou_3d
from lifter.clusters import grown_beyond
from lifter.fit import lift_fit, opened_at_border, visible_share
from lifter.ground import fit_ground_plane
from lifter.mono import box_up_of, solve_from_alpha
from lifter.placement import OUTLINE_FRONT, OUTLINE_REAR
from lifter.points import frame_points
from lifter.types import LABEL_SIDE_SIGMA_PX, Box2D, Prior
from tests.lifter.synth import IMAGE_SIZE, PLANE, make_frame


@pytest.fixture(autouse=True)
def plain_boxes(monkeypatch):
    """The synthetic cars are plain boxes: they touch the road at their corners, not on tyres."""
    monkeypatch.setattr("lifter.mono.CONTACT", {})


def _scenes(n_frames, seed, max_z=30.0):
    """Frames of three cars each, none hiding another (disjoint 2D boxes), all inside the image."""
    rng = np.random.default_rng(seed)
    frames = []
    while len(frames) < n_frames:
        boxes = np.array([[rng.uniform(-7, 7), 1.65, rng.uniform(6, max_z), rng.uniform(1.4, 1.7),
                           rng.uniform(1.5, 1.9), rng.uniform(3.6, 4.8), rng.uniform(-np.pi, np.pi)]
                          for _ in range(3)])
        fr = make_frame(boxes)
        bb = np.array([o.bbox for o in fr.objects])
        ov = iou_2d(bb, bb) - np.eye(3)
        inside = (bb[:, 0] > 2) & (bb[:, 2] < IMAGE_SIZE[0] - 3) & (bb[:, 3] < IMAGE_SIZE[1] - 3)
        if ov.max() == 0 and inside.all():
            frames.append((boxes, fr))
    return frames


def _lift(fr, noise_deg, rng, plane=None, outline="silhouette"):
    rect = fr.calib.lidar_to_rect(fr.velodyne[:, :3].astype(float))
    plane = fit_ground_plane(rect) if plane is None else plane
    pts = frame_points(fr.velodyne, fr.calib, plane)
    boxes = [Box2D("Car", o.bbox, 1.0) for o in fr.objects]
    priors = [Prior(np.array([o.h, o.w, o.l]), o.alpha + np.deg2rad(rng.uniform(-noise_deg, noise_deg)))
              for o in fr.objects]
    return lift_fit(boxes, priors, pts, fr.calib, IMAGE_SIZE, plane, outline=outline)


def test_fit_recovers_centre_and_yaw_on_64_beams_under_30m():
    rng = np.random.default_rng(0)
    lifted = [(boxes, _lift(fr, noise_deg=12.0, rng=rng)) for boxes, fr in _scenes(6, seed=1)]
    assert [len(out) for _, out in lifted] == [3] * 6
    for boxes, outs in lifted:
        for b, out in zip(boxes, outs):
            centre_err = np.linalg.norm(out.location - b[:3])
            yaw_err = abs(float(wrap_angle(out.rotation_y - b[6])))
            assert centre_err < 0.15, (b, out)
            assert np.rad2deg(yaw_err) < 5.0, (b, out)
            assert out.quality > 0.25  # fitted, not the fallback (0.2)


@pytest.mark.parametrize("beams", [16, 8])
def test_fit_stays_sane_with_few_beams(beams):
    rng = np.random.default_rng(1)
    errs = []
    for boxes, fr in _scenes(3, seed=2):
        fr = make_frame(boxes, beams=beams)
        errs += [np.linalg.norm(o.location - b[:3]) for b, o in zip(boxes, _lift(fr, 12.0, rng))]
    assert np.median(errs) < 0.15
    assert max(errs) < 0.5


@pytest.mark.parametrize("ry, eta, outline", [(-np.pi / 2, 0.7, OUTLINE_REAR),  # seen from behind
                                                (np.pi / 2, 0.56, OUTLINE_FRONT)])  # and the front
def test_a_ring_over_the_glass_or_bonnet_stands_the_face_in_front_of_it(ry, eta, outline):
    """A sparse scan's one ring crossed a car's rear window or bonnet, which lie inside the box (a
    car's glasshouse and bonnet are set in from its body: `placement.OUTLINE_*`): the fit puts the
    box's near face that far in front of the returns, at the truth, and keeps the yaw and the
    size."""
    car = np.array([2.0, 1.65, 12.0, 1.5, 1.7, 4.2, ry])
    fr = make_frame(car[None])
    rect = fr.calib.lidar_to_rect(fr.velodyne[:, :3].astype(float))
    near = 12.0 - 4.2 / 2
    height = 1.65 - rect[:, 1]
    face = (fr.hit_id == 0) & (rect[:, 2] < near + 0.01)
    h0 = height[face][np.argmin(np.abs(height[face] - eta * 1.5))]
    ring = face & (np.abs(height - h0) < 0.015)  # the laser that crosses it at eta of its height
    assert ring.sum() >= 20
    set_in = 4.2 * np.interp(height[ring] / 1.5, *outline)
    rect = rect[ring]
    rect[:, 2] += set_in
    fr.velodyne = np.concatenate([fr.velodyne[fr.hit_id == -1],
                                  np.column_stack([fr.calib.rect_to_lidar(rect),
                                                   np.full(len(rect), 0.5)]).astype(np.float32)])
    out = _lift(fr, 0.0, np.random.default_rng(0), plane=PLANE)[0]
    near_face = box_corners(np.array([[*out.location, *out.dims, out.rotation_y]]))[0][:, 2].min()
    assert set_in.min() > 0.3
    assert abs(near_face - near) < 0.03
    assert abs(np.rad2deg(wrap_angle(out.rotation_y - car[6]))) < 1.0
    np.testing.assert_allclose(out.dims[:2], car[3:5], atol=0.02)
    assert abs(out.dims[2] - car[5]) <= 0.011 * car[5]  # one step of the length grid


def test_ground_plane_from_the_scan():
    _, fr = _scenes(1, seed=3)[0]
    plane = fit_ground_plane(fr.calib.lidar_to_rect(fr.velodyne[:, :3].astype(float)))
    np.testing.assert_allclose(plane, PLANE, atol=2e-3)


def test_no_returns_falls_back_to_image_only_on_the_road():
    boxes, fr = _scenes(1, seed=4)[0]
    fr.velodyne = fr.velodyne[fr.hit_id < 0]  # the road alone
    out = _lift(fr, 0.0, np.random.default_rng(0), plane=PLANE, outline="box")
    assert len(out) == len(boxes) == len(fr.objects) == 3
    up = box_up_of("box", fr.calib)  # the synthetic labels' 2D boxes are KITTI's
    for o, b, lf in zip(fr.objects, boxes, out):
        sol = solve_from_alpha(np.array([o.h, o.w, o.l]), o.alpha, o.bbox, fr.calib, IMAGE_SIZE, PLANE,
                               box_up=up)
        np.testing.assert_allclose(lf.location, sol.location)
        np.testing.assert_allclose(lf.location, b[:3], atol=1e-3)
        d = np.hypot(b[0], b[2])  # the image's depth: trusted less with distance, as mono's
        assert lf.quality == pytest.approx(0.2 / (1.0 + d * d / (720.0 * 1.65)), rel=1e-4)


@pytest.mark.parametrize("box7", [[3.0, 1.65, 20.0, 1.5, 1.7, 4.2, 0.3],
                                  [-6.0, 1.9, 42.0, 1.9, 1.9, 5.1, -2.0],
                                  [1.0, 1.4, 9.0, 1.45, 1.8, 4.5, np.pi / 2]])
def test_height_from_the_projected_top_edge_is_exact(box7):
    """The 2D box is the 3D box's projection: its top, with the footprint and bottom known, gives
    the height back to rounding, whatever height the fit started from."""
    from kitti.boxes import project_boxes
    from kitti.calib import Calibration
    from lifter.placement import height_from_top

    calib = Calibration.kitti_default()
    b = np.array(box7, float)
    top = project_boxes(b[None], calib, IMAGE_SIZE)[0][1]
    dims = b[[3, 4, 5]].copy()
    for start in (0.8, 1.0, 1.3):
        dims[0] = b[3] * start
        assert height_from_top(b[:3], dims, b[6], top, calib.P(2)) == pytest.approx(b[3], abs=1e-9)
    dims[0] = b[3] * 0.4  # the top edge would need 2.5 x the fitted height: kept as it was
    assert height_from_top(b[:3], dims, b[6], top, calib.P(2)) == dims[0]
    # KITTI's 2D box projects the box upright in the LiDAR's frame: with that up, exact again
    up = box_up_of("box", calib)
    top = project_boxes(b[None], calib, IMAGE_SIZE, upright="lidar")[0][1]
    dims[0] = b[3]
    assert height_from_top(b[:3], dims, b[6], top, calib.P(2), up) == pytest.approx(b[3], abs=1e-5)


def test_visible_share_is_the_share_of_bearings_inside_the_image():
    """A thin box across the image's left border at 10 m, its bearings spread a degrees each side
    of the border's: half of it is seen; one inside the image all, one beyond the border none."""
    calib = Calibration.kitti_default()
    P = calib.P(2)
    cam_x = -P[0, 3] / P[0, 0]
    border = np.arctan(-P[0, 2] / P[0, 0])

    def across(lo, hi, z=10.0):  # heading along x: the box spans those bearings at depth z
        x_lo, x_hi = cam_x + z * np.tan(lo), cam_x + z * np.tan(hi)
        return np.array([0.5 * (x_lo + x_hi), 1.65, z]), np.array([1.5, 1e-6, x_hi - x_lo])

    a = np.deg2rad(6.0)
    for (lo, hi), share in [((border - a, border + a), 0.5), ((border + a, border + 3 * a), 1.0),
                            ((border - 3 * a, border - a), 0.0)]:
        T, dims = across(lo, hi)
        assert visible_share(T, dims, 0.0, P, IMAGE_SIZE[0]) == pytest.approx(share, abs=1e-6)


def _front_view_returns(car: np.ndarray, mirror: float, calib: Calibration):
    """Returns of a car facing the camera: its front face below the belt line, and the two door
    mirrors standing `mirror` m beyond its sides at 0.6-0.7 of its height, a quarter of its
    length back (bird's-eye x, z; image column; height above the road)."""
    x, _, z, h, w, l, _ = car
    face_x = np.linspace(x - w / 2, x + w / 2, 33)
    face_h = np.linspace(0.2, 0.5, 7) * h
    fx, fh = np.meshgrid(face_x, face_h)
    front = np.column_stack([fx.ravel(), np.full(fx.size, z - l / 2), fh.ravel()])
    mz, mh = np.meshgrid(np.linspace(z - l / 4 - 0.1, z - l / 4 + 0.1, 3), np.array([0.6, 0.7]) * h)
    mirrors = [np.column_stack([np.full(mz.size, x + s * (w / 2 + mirror)), mz.ravel(), mh.ravel()])
               for s in (-1, 1)]
    pts = np.concatenate([front] + mirrors)
    rect = np.column_stack([pts[:, 0], PLANE[3] - pts[:, 2], pts[:, 1]])
    return pts[:, :2], calib.rect_to_image(rect)[0][:, 0], pts[:, 2]


@pytest.mark.parametrize("labelled_w", [1.6, 1.6 + 2 * 0.114])
def test_a_front_views_width_is_the_one_the_2d_box_outlines(labelled_w):
    """Door mirrors stand 0.114 m beyond a car's body (VW Golf VII: 2.027 m across them, 1.799 m
    body): the generator's box holds them, KITTI's hugs the body. Seen from the front at 8 m,
    the returns measure either width, and the 2D box, KITTI's projection of the labelled box,
    picks the labelled one; the size prior (1.7 m) is neither."""
    from lifter.fit import _size_and_place

    calib = Calibration.kitti_default()
    P, up = calib.P(2), box_up_of("box", calib)
    body = np.array([0.3, 1.65, 8.0, 1.5, 1.6, 4.0, np.pi / 2])
    xz, u, height = _front_view_returns(body, 0.114, calib)
    label = body.copy()
    label[4] = labelled_w
    bbox = project_boxes(label[None], calib, IMAGE_SIZE, upright="lidar")[0]
    sensor = calib.lidar_to_rect(np.zeros((1, 3)))[0][[0, 2]]
    T, dims, *_ = _size_and_place(xz, u, height, 1.5, 1.7, 4.0, np.pi / 2, False, True, bbox,
                                  sensor, xz.mean(axis=0), P, IMAGE_SIZE[0], PLANE, up, LABEL_SIDE_SIGMA_PX,
                                  np.inf)
    assert dims[1] == pytest.approx(labelled_w, abs=1e-9)
    assert T[0] == pytest.approx(body[0], abs=1e-3)  # the 2D sides' rows and the centroid's pull


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_a_car_beside_the_camera_cut_by_the_border_is_fitted_from_the_returns_past_it(side):
    """A car parked beside the camera (KITTI's parked rows): the image shows its rear third, the
    scan its whole near side past the border. With a size/orientation prior 90 degrees off (what
    the network reads in such a cut crop) the box still lies along the car: its side, which the
    returns past the border show, cannot lie across a box a car's width wide."""
    box = np.array([side * 3.3, 1.65, 4.0, 1.59, 1.65, 4.04, -np.pi / 2])
    fr = make_frame(box)
    o = fr.objects[0]
    assert o.bbox[0] <= 1.0 if side < 0 else o.bbox[2] >= IMAGE_SIZE[0] - 2.0  # cut by the border
    pts = frame_points(fr.velodyne, fr.calib, PLANE)
    past = (pts.uv[:, 0] < 0) | (pts.uv[:, 0] > IMAGE_SIZE[0])
    assert past.sum() > 100  # the scan sees the car past the border
    prior = Prior(np.array([o.h, o.w, o.l]), float(wrap_angle(o.alpha + np.pi / 2)))
    out = lift_fit([Box2D("Car", o.bbox, 1.0)], [prior], pts, fr.calib, IMAGE_SIZE, PLANE)[0]
    yaw_err = abs(float(wrap_angle(2 * (out.rotation_y - box[6])))) / 2  # the axis, either way round
    assert np.rad2deg(yaw_err) < 3.0, out
    fitted = np.array([*out.location, *out.dims, out.rotation_y])
    assert iou_3d(box[None], fitted[None])[0, 0] > 0.8, out


def test_only_a_border_cut_side_is_opened():
    box = np.array([10.0, 100.0, 300.0, 200.0])
    assert np.array_equal(opened_at_border(box, 1242), box)
    assert np.array_equal(opened_at_border(np.array([0.0, 100.0, 1240.0, 374.0]), 1242),
                          [-np.inf, 100.0, np.inf, 374.0])
    assert np.array_equal(opened_at_border(np.array([1.5, 100.0, 1239.5, 374.0]), 1242),
                          [1.5, 100.0, 1239.5, 374.0])


def test_returns_past_the_border_join_only_while_the_object_stays_car_sized():
    """Past the border lie the car's hidden end (its own cluster, 0.2 m on) and, 3 m farther, a
    wall: the end joins, the wall would make the set longer than a car and stays out."""
    seen = np.stack([np.full(20, 2.0), np.linspace(3.0, 5.0, 20)], axis=1)  # a side face, x = 2
    hidden = np.stack([np.full(10, 2.0), np.linspace(1.8, 2.8, 10)], axis=1)
    wall = np.stack([np.full(10, 2.0), np.linspace(-2.0, -1.2, 10)], axis=1)
    joined = grown_beyond(seen, np.concatenate((hidden, wall)), diag=np.hypot(4.0, 1.7), strip=1.7)
    assert joined.tolist() == [True] * 10 + [False] * 10
