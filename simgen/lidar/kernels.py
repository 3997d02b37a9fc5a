"""Compiled per-hit loops of the sweep (numba): the steps that numpy would do in many passes over
gathered rows. Each is a plain function of arrays; scan.py documents the physics."""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def triangle_planes(v, f):
    """Per triangle (faces `f` into float32 vertices `v`): its plane as float64 rows (n, n . a),
    n the edge cross product (b - a) x (c - a), and 1 / |n| as float32, in one pass without the
    (F, 3, 3) gather (numpy's float64 cross product and norm: the same operations in the same
    order, so the same bits)."""
    plane = np.empty((f.shape[0], 4), np.float64)
    inv = np.empty(f.shape[0], np.float32)
    for i in range(f.shape[0]):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        ax, ay, az = np.float64(v[a, 0]), np.float64(v[a, 1]), np.float64(v[a, 2])
        ux, uy, uz = v[b, 0] - ax, v[b, 1] - ay, v[b, 2] - az
        wx, wy, wz = v[c, 0] - ax, v[c, 1] - ay, v[c, 2] - az
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        plane[i, 0], plane[i, 1], plane[i, 2] = nx, ny, nz
        plane[i, 3] = nx * ax + ny * ay + nz * az
        inv[i] = 1.0 / max(math.sqrt(nx * nx + ny * ny + nz * nz), 1e-30)
    return plane, inv


@numba.njit(cache=True, nogil=True)
def exact_hits(prim, tfar, ng, origins, dirs, plane):
    """Each hit's distance along its ray and its triangle's normal (in place in `tfar`, `ng`),
    from the hit triangle's plane: the range in float64, (n . a - n . o) / (n . d), and n as
    float32. Embree finds the triangle, but its own distance divides by an approximate
    reciprocal (rcpps and a Newton step) whose last bits differ between instruction sets and
    between Intel and AMD CPUs of one set, and its normal is rounded with or without fused
    multiply-adds as its kernels go; these are the same bits on every CPU. A ray parallel to
    the plane (n . d = 0) keeps Embree's range."""
    for i in range(prim.shape[0]):
        p = prim[i]
        if p < 0:
            continue
        den = plane[p, 0] * dirs[i, 0] + plane[p, 1] * dirs[i, 1] + plane[p, 2] * dirs[i, 2]
        if den != 0.0:
            num = plane[p, 3] - (plane[p, 0] * origins[i, 0] + plane[p, 1] * origins[i, 1]
                                 + plane[p, 2] * origins[i, 2])
            tfar[i] = np.float32(num / den)
        for a in range(3):
            ng[i, a] = np.float32(plane[p, a])


@numba.njit(cache=True, nogil=True)
def ray_origins(o0, ego_v, col_t, source, out):
    """Every ray's origin into `out` (N, 3) float32, rays ring-major: its column's, o0 + col_t *
    ego_v rounded to float32 (`ego_v` zero-length: o0, a still sensor), plus its laser's source
    `source` (N, 3; zero-length: none)."""
    columns = col_t.shape[0]
    col = np.empty((columns, 3), np.float32)
    for c in range(columns):
        for a in range(3):
            col[c, a] = np.float32(o0[a] + col_t[c] * ego_v[a]) if ego_v.shape[0] else np.float32(o0[a])
    has_src = source.shape[0] > 0
    for ring in range(out.shape[0] // columns):
        for c in range(columns):
            i = ring * columns + c
            for a in range(3):
                out[i, a] = col[c, a] + source[i, a] if has_src else col[c, a]


@numba.njit(cache=True, nogil=True)
def pass_candidates(prim, passes):
    """The rays whose hit is on a triangle that rays may pass (`passes` per triangle)."""
    out = np.empty(prim.shape[0], np.int64)
    k = 0
    for i in range(prim.shape[0]):
        p = prim[i]
        if p >= 0 and passes[p]:
            out[k] = i
            k += 1
    return out[:k]


@numba.njit(cache=True, nogil=True)
def _pane(t_n, c, r0):
    """One-way transmittance of a pane at incidence cos c: its normal-incidence value t_n times
    the rise of the Fresnel loss of both faces towards grazing (Schlick's approximation)."""
    c = min(max(c, 0.0), 1.0)
    fresnel = r0 + (1.0 - r0) * (1.0 - c) ** 5
    q = (1.0 - fresnel) / (1.0 - r0)
    return t_n * q * q


@numba.njit(cache=True, nogil=True)
def pass_prepare(cand, u, prim, tfar, ng, origins, d_w, inv_ng, tri_mat, mat_t, mat_p, tri_glass,
                 glass_planes, loss, pane_max, r0, step, cabin, cabin_depth):
    """One round of pass-through, before its query, over the rays `cand` (their hit: `prim`,
    `tfar`, `ng`). Glass lets the ray through the pane where it entered (`loss`, in place,
    takes the pane's two-way transmittance) and the ray crosses the glass solid to the nearest
    face it heads out through (its face planes). A solid thinner than `pane_max` is that one
    pane: the ray goes on. A thicker one is a vehicle's glasshouse. Entering it at height h of
    the pane (0 on its lowest face, 1 on its highest, the faces whose normals point most down
    and most up), the ray ends on the cabin `cabin_depth` behind the pane (or at its far side,
    if nearer) where its uniform `u` is below the share of that height band the cabin fills
    (`cabin` rows h0, h1, share; textures.glass_cabin_bands); leaving through a face that looks
    down (normal z < -0.5), it goes on into the body below the window line, the interior, and
    returns from there. Either way `tfar` moves to that point (the glass material's
    reflectivity is the interior's). Leaving through a side or the top, it passes the far pane
    too (`loss` takes that pane's transmittance) and goes on. A porous material lets the ray go
    on where `u` is below its porosity. Returns the rays that go on, and the origins,
    directions and start ranges (from the sensor) of their next query, `step` beyond the
    surface they leave, and how many of `cand` met glass."""
    n = cand.shape[0]
    sel = np.empty(n, np.int64)
    o2 = np.empty((n, 3), np.float32)
    d2 = np.empty((n, 3), np.float32)
    start = np.empty(n, np.float32)
    k = 0
    glass = 0
    for c in range(n):
        i = cand[c]
        t = prim[i]
        m = tri_mat[t]
        s = tfar[i]
        if mat_t[m] > 0:
            glass += 1
            g = tri_glass[t]
            x0 = origins[i, 0] + s * d_w[i, 0]
            x1 = origins[i, 1] + s * d_w[i, 1]
            x2 = origins[i, 2] + s * d_w[i, 2]
            best = np.inf
            c_out = 1.0
            z_out = 0.0
            z_lo, z_hi, below, above = 2.0, -2.0, 0.0, 0.0
            for f in range(glass_planes.shape[1]):
                nx, ny, nz = glass_planes[g, f, 0], glass_planes[g, f, 1], glass_planes[g, f, 2]
                inside = glass_planes[g, f, 3] - (nx * x0 + ny * x1 + nz * x2)
                if nx != 0.0 or ny != 0.0 or nz != 0.0:  # not a padding row
                    if nz < z_lo:
                        z_lo, below = nz, inside
                    if nz > z_hi:
                        z_hi, above = nz, inside
                nd = nx * d_w[i, 0] + ny * d_w[i, 1] + nz * d_w[i, 2]
                if nd > 1e-6:
                    dist = inside / nd
                    if dist < best:
                        best = dist
                        c_out = nd
                        z_out = nz
            depth = max(best, 0.0) if best < np.inf else 0.0
            c_in = abs(ng[i, 0] * d_w[i, 0] + ng[i, 1] * d_w[i, 1] + ng[i, 2] * d_w[i, 2]) * inv_ng[t]
            tr = _pane(mat_t[m], c_in, r0)
            if depth >= pane_max:
                h = max(below, 0.0) / max(max(below, 0.0) + max(above, 0.0), 1e-9)
                share = 0.0
                for b in range(cabin.shape[0]):
                    if cabin[b, 0] <= h < cabin[b, 1]:
                        share = cabin[b, 2]
                if u[c] < share:  # seats, head restraints, trim: the cabin returns
                    loss[i] *= tr * tr
                    tfar[i] = s + min(cabin_depth, depth)
                    continue
                if z_out < -0.5:  # into the body below the windows: the interior returns
                    loss[i] *= tr * tr
                    tfar[i] = s + depth
                    continue
                tr *= _pane(mat_t[m], c_out, r0)
            loss[i] *= tr * tr
            s += depth
        elif not u[c] < mat_p[m]:
            continue
        s += step
        sel[k] = i
        start[k] = s
        for a in range(3):
            d2[k, a] = d_w[i, a]
            o2[k, a] = origins[i, a] + s * d_w[i, a]
        k += 1
    return sel[:k], o2[:k], d2[:k], start[:k], glass


@numba.njit(cache=True, nogil=True, inline="always")
def _floor(x):
    """math.floor of a float64 x (|x| < 2 ** 63) as a float, without the helper call numba makes."""
    f = np.float64(np.int64(x))
    return f - 1.0 if f > x else f


@numba.njit(cache=True, nogil=True)
def window_returns(prim, tfar, d_w, origins, tri_wall, walls, panes, n_panes, loss, refl, t_unit, r0,
                   depth, gap, room_refl, curtain_refl):
    """Rays whose hit lies on a façade's window (simgen.lidar.windows: per wall face `walls` row
    tx, ty, s0, per_s, shift, foot, tile_v, pane set; per set `panes` rows u0, u1, v0, v1 of
    the glass, the mullion's u0, u1, curtain, the room's u0, u1, floor v, ceiling v, in tile
    units) go through the glazing (`loss`, in place, takes its two-way transmittance: `t_unit` at
    normal incidence times four faces' Fresnel rise, Schlick's with `r0`) and end `gap` behind
    it on a curtain (`refl` = curtain_refl x cos incidence, Lambertian) or in the room: on its
    back wall `depth` behind the glass, its side walls (the bay's edges), floor or ceiling,
    whichever the ray meets first (`refl` = room_refl, clutter). `tfar` moves there. Returns
    how many rays met a window."""
    hits = 0
    for i in range(prim.shape[0]):
        p = prim[i]
        if p < 0:
            continue
        w = tri_wall[p]
        if w < 0:
            continue
        s = tfar[i]
        dx, dy, dz = np.float64(d_w[i, 0]), np.float64(d_w[i, 1]), np.float64(d_w[i, 2])
        x = origins[i, 0] + s * dx
        y = origins[i, 1] + s * dy
        z = origins[i, 2] + s * dz
        tx, ty, per_s = walls[w, 0], walls[w, 1], walls[w, 3]
        u = (tx * x + ty * y - walls[w, 2]) * per_s + walls[w, 4]
        v = (z - walls[w, 5]) / walls[w, 6]
        if v < 0.0:
            continue
        fu, fv = u - _floor(u), v - _floor(v)
        k = int(walls[w, 7])
        j = -1
        for q in range(n_panes[k]):
            if (panes[k, q, 0] <= fu < panes[k, q, 1] and panes[k, q, 2] <= fv < panes[k, q, 3]
                    and not panes[k, q, 4] <= fu < panes[k, q, 5]):
                j = q
                break
        if j < 0:
            continue
        c = abs(dx * ty - dy * tx)  # the wall's normal is (ty, -tx, 0)
        if c < 1e-6:
            continue
        tr = _pane(t_unit, c, r0) * _pane(1.0, c, r0)  # two panes: the unit's value, four faces
        if panes[k, j, 6] > 0.0:
            path = gap / c
            rho = curtain_refl * c
        else:
            path = depth / c
            du = (dx * tx + dy * ty) * per_s  # tile units of u per metre of path
            if du > 0.0:
                path = min(path, (panes[k, j, 8] - fu) / du)
            elif du < 0.0:
                path = min(path, (panes[k, j, 7] - fu) / du)
            dv = dz / walls[w, 6]
            if dv > 0.0:
                path = min(path, (panes[k, j, 10] - fv) / dv)
            elif dv < 0.0:
                path = min(path, (panes[k, j, 9] - fv) / dv)
            rho = room_refl
        tfar[i] = s + np.float32(path)
        loss[i] *= np.float32(tr * tr)
        refl[i] = np.float32(rho)
        hits += 1
    return hits


@numba.njit(cache=True, nogil=True)
def pass_apply(sel, start, prim_q, tfar_q, ng_q, prim, tfar, ng, passes):
    """One round of pass-through, after its query: the rays `sel` take their new hit's triangle,
    range from the sensor and Ng row (in place; -1: the ray met nothing and returns nothing).
    Returns the rays whose new hit may pass on again."""
    n = sel.shape[0]
    nxt = np.empty(n, np.int64)
    k = 0
    for q in range(n):
        i = sel[q]
        p = prim_q[q]
        prim[i] = p
        if p < 0:
            continue
        tfar[i] = start[q] + tfar_q[q]
        for a in range(3):
            ng[i, a] = ng_q[q, a]
        if passes[p]:
            nxt[k] = i
            k += 1
    return nxt[:k]


@numba.njit(cache=True, nogil=True)
def _moved(rr, thr, d, o, n, dt, p0, vel, yaw, gamma):
    """Range and threshold of a hit at range `rr` on a moving actor, at the ray's own time `dt`
    after the actor's placement (see detect_rays: the facet plane moves with the actor's rigid
    motion). Per ray its direction `d`, origin `o` (x, y) and facet normal `n` (float32);
    per actor its placed origin `p0` (x, y), velocity `vel` and yaw rate `yaw`. Scalars only: a
    call per moving hit then costs no reference counting."""
    r64 = np.float64(rr)
    dx, dy, dz = np.float64(d[0]), np.float64(d[1]), np.float64(d[2])
    ex = vel[0] * dt
    ey = vel[1] * dt
    ez = vel[2] * dt
    if yaw != 0.0:
        relx = np.float64(o[0]) + r64 * dx - p0[0]
        rely = np.float64(o[1]) + r64 * dy - p0[1]
        a = yaw * dt
        ca, sa = math.cos(a), math.sin(a)
        ex += (ca - 1.0) * relx - sa * rely
        ey += sa * relx + (ca - 1.0) * rely
    nx, ny, nz = np.float64(n[0]), np.float64(n[1]), np.float64(n[2])
    nd = nx * dx + ny * dy + nz * dz
    if abs(nd) > 1e-3:
        shift = (nx * ex + ny * ey + nz * ez) / nd
        return np.float32(r64 + shift), np.float32(thr * (1.0 + gamma * shift / max(r64, 1e-3)))
    return rr, thr


@numba.njit(cache=True, nogil=True)
def detect_rays(prim, tfar, ng, d_w, origins, inv_ng, loss, refl, tri_refl, tri_expo, tri_actor,
                need_exp, need_scale, hidden, ext, u, beams, columns, drop, zero, detect, min_range,
                max_range, motion, first_moving, tri_slot, ray_time, placed_time, placed_origin,
                velocity, yaw_rate, gamma):
    """Every ray's return (scan.py, steps 3-5), the kept ones compacted. Rays are ring-major
    (ray i = ring * columns + column), so the per-laser values (`drop`, `zero`: one per ring)
    are read once per ring. A ray `hidden` (zero-length: none) returns nothing. Per ray with a
    hit:

    threshold: need = range ** need_exp * need_scale in float32 (LidarSpec.threshold, the same
    two roundings), on the true range;
    motion (if `motion` and the triangle is a moving actor's, index >= first_moving): the hit
    material point moves by the actor's rigid motion `delta` between its placement time and
    the ray's own time; the facet plane moves with it, so the range changes by
    (n . delta) / (n . d) (exact for pure translation, first order in the small yaw), in
    float64; the threshold follows to first order, need * (1 + gamma * shift / range) (the
    shift is centimetres: the actor is placed when the head faces it);
    echo: rho_eff = reflectivity * |cos incidence| ** k (* `loss`, glass; zero-length: none), or
    where `refl` is not negative (zero-length: nowhere) refl * loss (a beam that ended behind a
    window: window_returns);
    detection: rho_eff (* `ext`, two-way extinction; zero-length: clear air) >= need; then
    dropped where the ray's uniform `u` is below its laser's rate `drop`; the true range must
    lie in [min_range, max_range].

    The same uniform, rescaled past the drop-out (uniform again and independent of it), decides
    the reading (scan._read): below the laser's `zero` share the laser reads 0 (v = -1); above
    it, rescaled once more, it is the uniform v of the reading's scatter.
    Returns the kept rays, their true range, rho_eff, threshold, actor id and v."""
    n = prim.shape[0]
    idx_o = np.empty(n, np.int64)
    r_o = np.empty(n, np.float32)
    rho_o = np.empty(n, np.float32)
    need_o = np.empty(n, np.float32)
    aid_o = np.empty(n, np.int32)
    v_o = np.empty(n, np.float32)
    has_loss, has_refl, has_ext = loss.shape[0] > 0, refl.shape[0] > 0, ext.shape[0] > 0
    has_hidden = hidden.shape[0] > 0
    one = np.float32(1.0)
    k = 0
    for ring in range(beams):
        d = drop[ring]
        z = zero[ring]
        for i in range(ring * columns, (ring + 1) * columns):
            t = prim[i]
            if t < 0 or u[i] < d or (has_hidden and hidden[i]):
                continue
            rr = tfar[i]
            thr = np.float32(rr ** need_exp) * need_scale
            if motion and t >= first_moving:
                a = tri_slot[t]
                rr, thr = _moved(rr, thr, (d_w[i, 0], d_w[i, 1], d_w[i, 2]), (origins[i, 0], origins[i, 1]),
                                 (ng[i, 0], ng[i, 1], ng[i, 2]), ray_time[i] - placed_time[a],
                                 (placed_origin[a, 0], placed_origin[a, 1]),
                                 (velocity[a, 0], velocity[a, 1], velocity[a, 2]), yaw_rate[a], gamma)
            if rr < min_range or rr > max_range:
                continue
            e = tri_expo[t]
            if has_refl and refl[i] >= 0.0:
                rho = refl[i]
            elif e == 0.0:
                rho = tri_refl[t]
            else:
                c = abs(ng[i, 0] * d_w[i, 0] + ng[i, 1] * d_w[i, 1] + ng[i, 2] * d_w[i, 2]) * inv_ng[t]
                rho = tri_refl[t] * (c if e == 1.0 else c ** e)
            if has_loss:
                rho *= loss[i]
            if detect:
                p = rho * ext[i] if has_ext else rho
                if p < thr:
                    continue
            idx_o[k] = i
            r_o[k] = rr
            rho_o[k] = rho
            need_o[k] = thr
            aid_o[k] = tri_actor[t]
            w = (u[i] - d) / (one - d)  # uniform on [0, 1) again
            v_o[k] = -1.0 if w < z else (w - z) / (one - z)  # uniform on [0, 1) once more
            k += 1
    return idx_o[:k], r_o[:k], rho_o[:k], need_o[:k], aid_o[:k], v_o[:k]


@numba.njit(cache=True, nogil=True, inline="always")
def _rint(x):
    """np.rint of a float32 x >= 0 without the library call: adding 2 ** 23 leaves no fraction
    bits, so the sum rounds half to even as rint does, and taking it off again is exact; from
    2 ** 23 up every float32 is an integer already."""
    big = np.float32(8388608.0)
    return (x + big) - big if x < big else x


@numba.njit(cache=True, nogil=True)
def read_returns(idx, r, rho, need, v, clamp_v, scatter, ext, noise, noise_sigma, bias, gain,
                 floor_power, need0, floor0, per_step, k_max, dirs4, source, ring_t, az_t, time_t):
    """The output rows (scan.py, steps 5 and 7), in float32. Per return: the range takes its
    laser's `bias` and its standard normal `noise` * `noise_sigma` (zero-length: neither); the
    reading is 0 where v < 0 (the laser's zero share), and where the echo, gain * scatter[clamp_v]
    * rho_eff (* `ext`, two-way extinction; zero-length: clear air), is below floor_power * need
    (the intensity's clamp, decided on a scatter draw of its own); else the reading is s = gain *
    scatter[v] * rho_eff (* ext), dimmed by need0 / need where that is below 1 (no range
    compensation beyond the range whose threshold is need0); `scatter` holds the scatter's
    quantiles at len(scatter) equal steps of a uniform. s reads 0 below floor0, else k /
    per_step, k = round(s * per_step) <= k_max. A return lies at its ray's `source` (N, 3;
    zero-length: the origin) + range x direction. Positions, then readings: two short loops
    keep their arrays in registers, where one long loop spills them."""
    n = idx.shape[0]
    points = np.empty((n, 4), np.float32)
    ring = np.empty(n, np.uint8)
    az = np.empty(n, np.float32)
    tm = np.empty(n, np.float32)
    noisy = noise.shape[0] > 0
    has_ext = ext.shape[0] > 0
    has_src = source.shape[0] > 0
    n_q = scatter.shape[0]
    for k in range(n):  # positions
        i = np.uint64(idx[k])
        lz = ring_t[i]
        ring[k] = lz
        az[k] = az_t[i]
        tm[k] = time_t[i]
        rr = r[k]
        if noisy:
            rr = rr + bias[lz] + noise[k] * noise_sigma
        if has_src:
            for a in range(3):
                points[k, a] = dirs4[i, a] * rr + source[i, a]
        else:
            for a in range(3):
                points[k, a] = dirs4[i, a] * rr
    for k in range(n):  # readings
        value = np.float32(0.0)
        if v[k] >= 0:
            echo = gain[ring[k]] * rho[k]
            if has_ext:
                echo *= ext[k]
            if echo * scatter[min(int(clamp_v[k] * n_q), n_q - 1)] >= floor_power * need[k]:
                s = echo * scatter[min(int(v[k] * n_q), n_q - 1)]
                if need[k] > need0:
                    s *= need0 / need[k]
                if s >= floor0:
                    value = min(_rint(s * per_step), k_max) / per_step
        points[k, 3] = value
    return points, ring, az, tm
