"""KITTI labels derived from the world and the renders, never typed in.

Per actor:
- silhouette: the union of its parts' projections (cut at a 5 cm near plane), an exact polygon
  in image_2 pixels (pixel centres at integer coordinates, as in KITTI);
- 2D box, as KITTI's: the projection of the label's own 3D box (its numbers as written) stood
  upright in the LiDAR's (the rig's reference) frame (KITTI annotated yaw-only boxes in the
  Velodyne clouds and projected them; label_2 keeps a yaw about camera y only, so its 3D box is
  tilted from that one by the calibration's 0.6 deg of pitch and of roll): its corners, cut at
  the near plane when the box reaches behind the camera, their bounds clamped to pixel indices
  [0, W-1] x [0, H-1]. So every row's box is `kitti.boxes.project_boxes(box7, calib, size,
  upright="lidar")` of the row itself, on a tilted or graded road as on a flat one, truncated or
  not. On the real dev frames the vehicles' boxes lie a median 0.2 px from that projection and
  0.6 px from the label box's own. The box is a little larger than the mesh's silhouette, whose
  own box goes to meta/ as `silhouette_bbox`. For the classes in `silhouette_sides` (default
  Pedestrian) the left and right sides are the silhouette's, as KITTI's devkit says its
  pedestrians' were labelled again in the image (width over the projection's, median: 0.81 on
  the real dev frames' three, 0.82 on 200 frames of `scenes/urban.yaml`);
- truncation: the share of the silhouette's area outside the image (the mesh, not the box); an
  object reaching behind the camera plane projects without bound, so its truncation is ~1;
- visible share: the actor's instance-mask pixels over the area of its silhouette inside the
  image (what it would cover with nothing in front of it); capped at 1;
- occlusion: 0 if visible share >= `occlusion_partly_below` (default 0.8), 1 if >= 
  `occlusion_largely_below` (default 0.3), else 2;
- h, w, l: the mesh's extent in its own frame; location: its bottom-face centre in rectified
  camera-0 coordinates; rotation_y from its heading in that frame (heading (cos ry, 0, -sin ry));
  alpha from rotation_y and the location via kitti.boxes.
An actor in view with no visible pixel gets no row. One whose 2D box is lower than
`min_height_px`, whose distance (x-z plane, from camera 0) exceeds `max_distance`, whose
visible share is below `min_visible_share`, or with fewer than `min_lidar_points` LiDAR returns
on it gets a DontCare row with its 2D box.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from kitti.boxes import alpha_from_rotation_y, project_boxes, wrap_angle
from kitti.labels import Object3D

from .spec import LabelRules
from .world import Actor, World

NEAR = 0.05


@dataclass
class ActorTruth:
    """What the labeller found for one actor (all actors, in view or not, go to meta/)."""

    id: int
    cls: str
    box7: np.ndarray  # [x, y, z, h, w, l, ry] in rect camera-0 coords
    in_view: bool
    bbox: np.ndarray | None  # (4,) the label's clipped 2D box (see the module), None when out of view
    truncation: float
    visible_px: int
    visible_share: float
    distance: float
    label: str  # "label", "dontcare", "hidden" or "out_of_view"
    occluded: int = -1
    silhouette_bbox: np.ndarray | None = None  # (4,) clipped box of the mesh's silhouette


def _clip_near(tri: np.ndarray) -> list[np.ndarray]:
    """Cut triangles (N, 3, 3) crossing z = NEAR; returns polygons on the visible side."""
    out = []
    for t in tri:
        poly = []
        for i in range(3):
            a, b = t[i], t[(i + 1) % 3]
            if a[2] >= NEAR:
                poly.append(a)
            if (a[2] >= NEAR) != (b[2] >= NEAR):
                s = (NEAR - a[2]) / (b[2] - a[2])
                poly.append(a + s * (b - a))
        if len(poly) >= 3:
            out.append(np.array(poly))
    return out


def _project(v: np.ndarray, K: np.ndarray) -> np.ndarray:
    uvw = v @ K.T
    return uvw[..., :2] / uvw[..., 2:3]


def _convex_part_outline(v: np.ndarray, edges: np.ndarray, K: np.ndarray) -> shapely.Geometry | None:
    """Image outline of a convex part: the hull of its projected vertices in front of the near
    plane and of its edges' crossings of that plane (the projection of the clipped solid)."""
    front = v[v[:, 2] >= NEAR]
    a, b = v[edges[:, 0]], v[edges[:, 1]]
    cross = (a[:, 2] >= NEAR) != (b[:, 2] >= NEAR)
    if np.any(cross):
        a, b = a[cross], b[cross]
        s = (NEAR - a[:, 2]) / (b[:, 2] - a[:, 2])
        front = np.concatenate([front, a + s[:, None] * (b - a)])
    if len(front) < 3:
        return None
    return shapely.convex_hull(shapely.MultiPoint(_project(front, K)))


def silhouette(actor: Actor, cam_from_world: np.ndarray, K: np.ndarray) -> shapely.Geometry | None:
    """The exact image-plane silhouette of an actor, or None if it is behind the camera.

    Procedural actors are unions of convex parts: the silhouette is the union of the parts'
    projected hulls (one vectorised shapely call). User meshes may be anything: the union of
    their projected triangles. Each part's vertices are transformed and projected by a product
    of their own (as many small matrix products as parts: the same bits whatever the batch);
    everything elementwise runs on all parts at once."""
    M = cam_from_world @ actor.pose
    rot, shift = M[:3, :3].T, M[:3, 3]
    meshes = [p.mesh for p in actor.parts]
    verts = [np.asarray(m.vertices).view(np.ndarray) @ rot + shift for m in meshes]
    sizes = [len(v) for v in verts]
    starts = np.cumsum([0, *sizes[:-1]])
    z = np.concatenate([v[:, 2] for v in verts])
    zmin, zmax = np.minimum.reduceat(z, starts), np.maximum.reduceat(z, starts)
    if float(zmax.max()) < NEAR:
        return None
    geoms = []
    if actor.recipe.get("kind") != "user":
        whole = np.flatnonzero(zmin >= NEAR).tolist()
        if whole:
            uvw = np.concatenate([verts[i] @ K.T for i in whole])
            pts = uvw[..., :2] / uvw[..., 2:3]
            idx = np.repeat(np.arange(len(whole)), [sizes[i] for i in whole])
            geoms += list(shapely.convex_hull(shapely.multipoints(pts, indices=idx)))
        for i in np.flatnonzero((zmin < NEAR) & (NEAR <= zmax)).tolist():
            g = _convex_part_outline(verts[i], np.asarray(meshes[i].edges_unique), K)
            if g is not None:
                geoms.append(g)
    else:
        for m, v in zip(meshes, verts):
            tri = v[np.asarray(m.faces)]
            zmin = tri[:, :, 2].min(axis=1)
            cut = (zmin < NEAR) & (tri[:, :, 2].max(axis=1) >= NEAR)
            geoms += list(shapely.polygons(_project(tri[zmin >= NEAR], K)))
            geoms += [shapely.Polygon(_project(q, K)) for q in _clip_near(tri[cut])]
    if not geoms:
        return None
    geoms = np.array(geoms, dtype=object)
    geoms = geoms[shapely.area(geoms) > 0]
    return shapely.union_all(geoms) if len(geoms) else None


_BOX_CORNERS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
_BOX_EDGES = np.array([[a, b] for a in range(8) for b in range(a + 1, 8)
                       if bin(a ^ b).count("1") == 1])  # the 12 edges: corners differing in one axis


def box_outline(lo: np.ndarray, hi: np.ndarray, cam_from_actor: np.ndarray,
                K: np.ndarray) -> shapely.Geometry | None:
    """Image outline of the actor's 3D box (its extent lo..hi in its own frame)."""
    corners = lo + _BOX_CORNERS * (hi - lo)
    v = corners @ cam_from_actor[:3, :3].T + cam_from_actor[:3, 3]
    if v[:, 2].max() < NEAR:
        return None
    return _convex_part_outline(v, _BOX_EDGES, K)


def _as_written(box7: np.ndarray) -> np.ndarray:
    """The box as its label row states it (four decimals), so the 2D box is that of the row."""
    return np.array([float(f"{v:.4f}") for v in box7])


def _clipped_bounds(outline: shapely.Geometry, image: shapely.Geometry, W: int,
                    H: int) -> np.ndarray:
    x1, y1, x2, y2 = outline.intersection(image).bounds
    return np.array([max(x1, 0.0), max(y1, 0.0), min(x2, W - 1.0), min(y2, H - 1.0)])


def derive(world: World, instance: np.ndarray, rules: LabelRules,
           lidar_points: dict[int, int] | None = None) -> tuple[list[Object3D], list[ActorTruth]]:
    """Label rows (objects first, DontCare after) and the per-actor truth of one frame;
    `lidar_points` (returns per actor id) is needed when the rules count them."""
    if rules.min_lidar_points and lidar_points is None:
        raise ValueError("labels.min_lidar_points counts LiDAR returns: this frame has no scan")
    rig = world.rig
    W, H = rig.width, rig.height
    image = shapely.box(-0.5, -0.5, W - 0.5, H - 0.5)
    cam = rig.cam2_from_world()
    K = rig.intrinsics()
    rect_from_world = rig.calib.velo_to_rect @ np.linalg.inv(rig.reference_pose)
    counts = np.bincount(instance.ravel(), minlength=max((a.id for a in world.actors), default=0) + 1)
    rows, dontcare, truths = [], [], []
    for actor in world.actors:
        allv = np.concatenate([p.mesh.vertices for p in actor.parts])
        lo, hi = allv.min(axis=0), allv.max(axis=0)
        l, w, h = hi - lo
        centre = actor.pose @ np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2], 1.0])
        loc = (rect_from_world @ centre)[:3]
        head = rect_from_world[:3, :3] @ actor.pose[:3, 0]
        ry = float(wrap_angle(np.arctan2(-head[2], head[0])))
        box7 = np.array([*loc, h, w, l, ry])
        dist = float(np.hypot(loc[0], loc[2]))
        # Every part lies inside the box lo..hi: a box whose image misses the frame spares the
        # union of the parts' outlines (half the actors stand beside or behind the camera).
        reach = box_outline(lo, hi, cam @ actor.pose, K)
        sil = silhouette(actor, cam, K) if reach is not None and reach.intersects(image) else None
        inside = sil.intersection(image) if sil is not None else None
        bbox = (project_boxes(_as_written(box7)[None], rig.calib, (W, H), upright="lidar")[0]
                if inside is not None and inside.area > 0 else None)
        if bbox is None or not np.isfinite(bbox).all():  # no pixel, or a box behind the camera
            truths.append(ActorTruth(actor.id, actor.cls, box7, False, None, 1.0, 0, 0.0, dist,
                                     "out_of_view"))
            continue
        sil_bbox = _clipped_bounds(inside, image, W, H)
        if actor.cls in rules.silhouette_sides:
            bbox[[0, 2]] = sil_bbox[[0, 2]]
        trunc = float(np.clip(1.0 - inside.area / sil.area, 0.0, 1.0))
        vis_px = int(counts[actor.id]) if actor.id < len(counts) else 0
        share = float(min(1.0, vis_px / inside.area))
        t = ActorTruth(actor.id, actor.cls, box7, True, bbox, trunc, vis_px, share, dist, "label",
                       silhouette_bbox=sil_bbox)
        truths.append(t)
        if vis_px == 0:
            t.label = "hidden"
        elif (bbox[3] - bbox[1] < rules.min_height_px or dist > rules.max_distance
              or share < rules.min_visible_share
              or (rules.min_lidar_points and lidar_points.get(actor.id, 0) < rules.min_lidar_points)):
            t.label = "dontcare"
            dontcare.append(Object3D.dont_care(bbox))
        else:
            t.occluded = (0 if share >= rules.occlusion_partly_below
                          else 1 if share >= rules.occlusion_largely_below else 2)
            alpha = float(alpha_from_rotation_y(ry, loc[0], loc[2]))
            rows.append(Object3D(actor.cls, round(trunc, 2), t.occluded, alpha, bbox, h, w, l, loc, ry))
    return rows + dontcare, truths
