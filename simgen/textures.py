"""Procedural surface detail for the camera: asphalt, paving, façades, grass, foliage, bark, wood,
and on vehicles glass, number plates and paint. The façade tiles' windows are also materials the
LiDAR meets (`windows`, simgen.lidar.windows).

Each texture is a tile of multipliers on a material's flat colour (mean about 1, so a surface
keeps the albedo its material gives it, and the LiDAR, which reads the material, agrees with the
camera on average). Tiles are made in code from fractal noise synthesised in the frequency domain
(white noise shaped by a 1/f^beta spectrum), which is periodic by construction: the tiles repeat
without seams. A tile is a pure function of (kind, variant): each worker process builds the bank
once and every frame picks variants from its own seed, so images stay byte-identical with any
number of workers.

`TILE_M` is the size of a tile in metres on the surface (the renderer maps world coordinates to
texture coordinates with it); the feature sizes inside a tile are in metres too and come from
the construction standards or common practice named beside them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

SIZE = 512  # texels per tile side
# Multipliers up to MAX_GAIN are stored as uint8 (255 = MAX_GAIN: steps of 1 %); the renderer
# scales the vertex colour by MAX_GAIN.
MAX_GAIN = 2.5
# One tile per kind and worker: a texture stays in the GL context only while consecutive frames
# use it, and uploading one costs milliseconds on a software renderer; frames differ by the
# tile's offset, scale and colour instead (simgen.render).
VARIANTS = 1

# Metres per tile (u, v) on the surface.
TILE_M = {"asphalt": (6.0, 6.0), "marking": (4.0, 4.0), "paving": (3.0, 3.0),
          "concrete": (3.0, 3.0), "grass": (4.0, 4.0), "soil": (4.0, 4.0), "sand": (4.0, 4.0),
          "foliage": (2.5, 2.5), "bark": (1.0, 2.0), "planks": (2.4, 2.4), "metal": (2.0, 2.0),
          "roof": (6.0, 6.0), "plaster": (6.0, 6.4), "brick": (6.0, 6.4)}
# Façade tiles hold two window bays by two storeys: a bay of 3.0 m and a storey of 3.2 m
# (residential storey heights 2.75-3.5 m floor to floor; a window per 2.5-3.5 m of front).
BAY_M, STOREY_M = 3.0, 3.2


def _fractal(rng: np.random.Generator, beta: float, size: int | tuple[int, int] = SIZE,
             aspect: float = 1.0) -> np.ndarray:
    """Zero-mean, unit-sd periodic noise of shape `size` (rows, columns) with a 1/f^beta
    amplitude spectrum; `aspect` > 1 stretches features along the rows' direction (v)."""
    rows, cols = (size, size) if isinstance(size, int) else size
    fy = np.fft.fftfreq(rows)[:, None] * aspect
    fx = np.fft.fftfreq(cols)[None, :]
    f = np.hypot(fx, fy)
    f[0, 0] = 1.0
    amp = f ** -beta
    amp[0, 0] = 0.0
    spectrum = np.fft.fft2(rng.standard_normal((rows, cols))) * amp
    n = np.real(np.fft.ifft2(spectrum))
    return (n - n.mean()) / max(float(n.std()), 1e-12)


def _grain(rng: np.random.Generator, sigma_px: float = 0.7) -> np.ndarray:
    """Fine aggregate-like grain: white noise blurred by a Gaussian of sigma_px texels (in the
    frequency domain, so it stays periodic), unit sd."""
    f2 = np.fft.fftfreq(SIZE)[:, None] ** 2 + np.fft.fftfreq(SIZE)[None, :] ** 2
    spectrum = np.fft.fft2(rng.standard_normal((SIZE, SIZE))) * np.exp(-2 * np.pi**2 * sigma_px**2 * f2)
    n = np.real(np.fft.ifft2(spectrum))
    return (n - n.mean()) / max(float(n.std()), 1e-12)


def _grid_lines(period_px: float, width_px: float, size: int = SIZE) -> np.ndarray:
    """1 on joints of a periodic line pattern along one axis (0..size texels), else 0."""
    x = np.arange(size) % period_px
    return ((x < width_px) | (x > period_px - width_px / 2)).astype(np.float32)


def _asphalt(rng: np.random.Generator) -> np.ndarray:
    """Grain of the aggregate, darker and lighter patches (repairs, wear), cracks, oil stains."""
    m = 1.0 + 0.22 * _grain(rng) + 0.12 * _fractal(rng, 1.4)
    patches = _fractal(rng, 2.6)
    m *= np.where(patches > 1.1, 0.82, np.where(patches < -1.3, 1.12, 1.0))
    ridge = np.abs(_fractal(rng, 2.0))
    m *= np.where(ridge < 0.025, 0.55, 1.0)  # crack lines: the zero set of smooth noise
    stains = _fractal(rng, 2.2)
    m *= np.where(stains > 2.0, 0.75, 1.0)
    return np.repeat(m[..., None], 3, axis=2)


def _marking(rng: np.random.Generator) -> np.ndarray:
    """Line paint worn through to the asphalt in patches (worn paint, about 10-20 % of the area)."""
    wear = _fractal(rng, 1.8) + 0.35 * _grain(rng, 1.5)
    m = np.where(wear > 1.0, 0.2, 1.0) * (1.0 + 0.06 * _grain(rng))
    return np.repeat(m[..., None], 3, axis=2)


def _paving(rng: np.random.Generator) -> np.ndarray:
    """Concrete slabs of 0.5 m (DIN 485 paving slabs, 50 x 50 cm) with dark joints, each slab a
    little lighter or darker, plus grain."""
    per = SIZE * 0.5 / TILE_M["paving"][0]
    joints = np.maximum(_grid_lines(per, 2.0)[None, :], _grid_lines(per, 2.0)[:, None])
    idx = (np.arange(SIZE) // per).astype(int)
    slab = rng.normal(1.0, 0.06, (idx.max() + 1, idx.max() + 1))[idx[:, None], idx[None, :]]
    m = slab * (1.0 + 0.14 * _grain(rng) + 0.08 * _fractal(rng, 1.6)) * (1.0 - 0.5 * joints)
    return np.repeat(m[..., None], 3, axis=2)


def _concrete(rng: np.random.Generator) -> np.ndarray:
    m = 1.0 + 0.08 * _grain(rng) + 0.08 * _fractal(rng, 1.8)
    return np.repeat(m[..., None], 3, axis=2)


def _grass(rng: np.random.Generator) -> np.ndarray:
    """Blades (fine high-contrast noise), clumps, and dry yellow-brown patches."""
    fine = _grain(rng, 0.8)
    clumps = _fractal(rng, 1.5)
    dry = np.clip(_fractal(rng, 2.4) - 0.6, 0.0, None)
    v = np.exp(0.35 * fine + 0.2 * clumps)
    return np.stack([v * (1.0 + 0.9 * dry), v * (1.0 + 0.25 * dry), v * (1.0 - 0.2 * dry)], axis=2)


def _foliage(rng: np.random.Generator) -> np.ndarray:
    """Leaf clusters and the dark gaps between them: strong contrast at a few centimetres, the
    hue shifting from yellow-green to blue-green across the crown."""
    leaves = _fractal(rng, 0.9) + 0.5 * _grain(rng, 1.2)
    v = np.exp(0.6 * leaves) * np.where(leaves < -0.9, 0.2, 1.0)
    hue = 0.06 * _fractal(rng, 2.0)
    return np.stack([v * (1.0 + hue), v, v * (1.0 - hue)], axis=2)


def _bark(rng: np.random.Generator) -> np.ndarray:
    """Vertical furrows: noise stretched along the trunk."""
    m = np.exp(0.30 * _fractal(rng, 1.2, aspect=8.0) + 0.10 * _grain(rng))
    return np.repeat(m[..., None], 3, axis=2)


def _planks(rng: np.random.Generator) -> np.ndarray:
    """Vertical boards of 0.12 m with 1.5 cm gaps (a common board fence), grain along the boards."""
    per = SIZE * 0.12 / TILE_M["planks"][0]
    gaps = _grid_lines(per, per * 0.015 / 0.12 + 1.0)[None, :]
    idx = (np.arange(SIZE) // per).astype(int)
    board = rng.normal(1.0, 0.08, idx.max() + 1)[idx][None, :]
    m = board * np.exp(0.12 * _fractal(rng, 1.3, aspect=10.0)) * (1.0 - 0.75 * gaps)
    return np.repeat(m[..., None], 3, axis=2)


def _metal(rng: np.random.Generator) -> np.ndarray:
    m = 1.0 + 0.05 * _grain(rng) + 0.08 * _fractal(rng, 2.0, aspect=4.0)
    return np.repeat(m[..., None], 3, axis=2)


@dataclass(frozen=True)
class Window:
    """One window of a façade tile, in tile units (u across from the tile's left, v up from its
    foot), for the LiDAR (simgen.lidar.windows): where the glass is, the mullion across it, a
    curtain behind it or not, and the room behind it (its bay, its storey's floor and ceiling)."""

    glass: tuple[float, float, float, float]  # u0, u1, v0, v1
    mullion: tuple[float, float]  # u0, u1
    curtain: bool
    room: tuple[float, float, float, float]  # u0, u1, floor v, ceiling v


# A storey's clear height: the storey of 3.2 m less a floor of 0.3 m (a 0.2 m concrete slab
# under screed and its insulation; German building codes ask 2.4 m of clear height in rooms).
CLEAR_M = STOREY_M - 0.3


def _windows(rng: np.random.Generator, base: np.ndarray, record: list | None) -> np.ndarray:
    """Two bays by two storeys of windows on a wall multiplier: 1.2-1.6 m wide, sill 0.9 m and
    head 2.6 m above the floor (common residential window sizes), dark glass brighter towards
    the top (the sky it mirrors), a light frame, a sill; curtains in some. Each is appended to
    `record` (a list; None: not recorded)."""
    m = base.copy()
    tu, tv = TILE_M["plaster"]
    px_u, px_v = SIZE / tu, SIZE / tv
    for bay in range(2):
        for storey in range(2):
            w = rng.uniform(1.2, 1.6)
            u0 = int((bay * BAY_M + (BAY_M - w) / 2) * px_u)
            u1 = int(u0 + w * px_u)
            # Rows run down the image: v = 0 is the top of the tile (texture coordinates flip).
            top = int(SIZE - (storey * STOREY_M + 2.6) * px_v)
            bot = int(SIZE - (storey * STOREY_M + 0.9) * px_v)
            f = 4  # frame, texels (about 5 cm)
            m[top - f:bot + f, u0 - f:u1 + f] = 1.35
            glass = np.linspace(0.45, 0.12, bot - top)[:, None, None] * rng.uniform(0.7, 1.3)
            m[top:bot, u0:u1] = glass * np.array([0.95, 1.0, 1.1])
            curtain = bool(rng.uniform() < 0.4)
            if curtain:
                m[top:bot, u0:u1] = np.maximum(m[top:bot, u0:u1], rng.uniform(0.5, 0.9))
            mid = (u0 + u1) // 2
            m[top:bot, mid - 2:mid + 2] = 1.3  # mullion
            m[bot + f:bot + 3 * f, u0 - 2 * f:u1 + 2 * f] = 1.15  # sill
            if record is not None:
                record.append(Window((u0 / SIZE, u1 / SIZE, (SIZE - bot) / SIZE, (SIZE - top) / SIZE),
                                      ((mid - 2) / SIZE, (mid + 2) / SIZE), curtain,
                                      (bay * BAY_M / tu, (bay + 1) * BAY_M / tu, storey * STOREY_M / tv,
                                       (storey * STOREY_M + CLEAR_M) / tv)))
    return m


def _plaster(rng: np.random.Generator, record: list | None = None) -> np.ndarray:
    """Rendered wall with weathering streaks running down, and windows."""
    wall = 1.0 + 0.08 * _grain(rng) + 0.08 * _fractal(rng, 1.8, aspect=4.0)
    return _windows(rng, np.repeat(wall[..., None], 3, axis=2), record)


def _brick(rng: np.random.Generator, record: list | None = None) -> np.ndarray:
    """Stretcher bond of 240 x 71 mm bricks (German NF) in 10 mm mortar joints, and windows."""
    px = SIZE / TILE_M["brick"][0]
    # A whole number of courses and bricks per tile, so that the bond repeats without a seam.
    course = SIZE / round(TILE_M["brick"][1] / 0.081)
    length = SIZE / round(TILE_M["brick"][0] / 0.25)
    v, u = np.mgrid[0:SIZE, 0:SIZE].astype(np.float32)
    row = np.floor(v / course).astype(int)
    shift = (row % 2) * length / 2
    col = np.floor((u + shift) / length).astype(int)
    mortar = ((v % course) < 0.010 * px) | (((u + shift) % length) < 0.010 * px)
    tone = rng.normal(1.0, 0.10, (row.max() + 1, col.max() + 2))[row, col]
    wall = np.where(mortar, 1.35, tone * (1.0 + 0.06 * _grain(rng)))
    return _windows(rng, np.repeat(wall[..., None], 3, axis=2), record)


def _roof(rng: np.random.Generator) -> np.ndarray:
    m = 1.0 + 0.12 * _fractal(rng, 1.5) + 0.05 * _grain(rng)
    return np.repeat(m[..., None], 3, axis=2)


# Vehicle glass and number plates (simgen.render maps them per part, not in metres of the world).
# A pane is a mirror over a see-through cabin: from 10-20 m the camera sees headrests and seat
# backs against the bright scene beyond the far windows, and the sky mirrored at the top; a pane
# of one flat colour, as the meshes alone give, is what no photographed car shows. A tile spans
# GLASS_TILE_M of glass along the car and the pane's whole height (row 0 at its top).
GLASS_TILE_M = 2.4
# Seats: head restraints about 0.25-0.28 m wide and 0.2 m tall (ECE R17 asks at least 0.17 m
# wide), their tops about 0.75 m above the seat; two a row, 0.5-0.6 m apart (the seats' centres).
HEADREST_W, HEADREST_PITCH = 0.26, 0.55
# The glass tile's rows, from its top (v): the mirrored sky above GLASS_SKY_V, the scene through the
# far windows down to GLASS_TRIM_V, trim and cushions below; seat backs SEAT_BACK_W wide from
# SEAT_BACK_V down, head restraints HEADREST_V +- HEADREST_HALF_V (a pane about 0.9 m tall).
GLASS_SKY_V, GLASS_TRIM_V, SEAT_BACK_V, SEAT_BACK_W = 0.2, 0.65, 0.5, 0.44
HEADREST_V, HEADREST_HALF_V = 0.36, 0.08
# EU plates (DIN 74069): 520 x 110 mm, a blue band 40 mm wide on the left, black characters 75 mm
# tall (drawn 40 mm wide) inside a thin black rim (drawn 4 mm); up to 8 characters (a judgement).
PLATES_PER_TILE, PLATE_CHARS = 4, 8


def _seat_pitch() -> float:
    """Seat spacing along the glass tile: whole seats per tile, so the tile has no seam."""
    return GLASS_TILE_M / round(GLASS_TILE_M / HEADREST_PITCH)


def glass_cabin_bands() -> np.ndarray:
    """(3, 3) rows (h0, h1, share): over the heights h0..h1 of a car's pane (0 at its foot, 1 at
    its top, as the renderer maps the tile), the share of the pane's length where the glass tile
    shows the cabin (trim and cushions, seat backs, head restraints, their corners taken square)
    rather than the scene through the far windows: where the LiDAR's beam ends inside (simgen.lidar).
    """
    pitch = _seat_pitch()
    return np.array([[0.0, 1.0 - GLASS_TRIM_V, 1.0],
                     [1.0 - GLASS_TRIM_V, 1.0 - SEAT_BACK_V, SEAT_BACK_W / pitch],
                     [1.0 - HEADREST_V - HEADREST_HALF_V, 1.0 - HEADREST_V + HEADREST_HALF_V,
                      HEADREST_W / pitch]])


def _glass(rng: np.random.Generator) -> np.ndarray:
    """Top fifth: the mirrored sky, streaked; the middle: the bright scene seen through the far
    windows, with the seats dark against it (a back SEAT_BACK_W wide rising from the trim, a head
    restraint above it); the bottom third: trim and seat cushions, dark. Reflections of what
    stands around (low-frequency streaks) over all of it."""
    v = (np.arange(SIZE) + 0.5)[:, None] / SIZE  # 0 at the pane's top
    u_m = (np.arange(SIZE) + 0.5)[None, :] / SIZE * GLASS_TILE_M
    m = np.where(v < GLASS_SKY_V, 1.15, np.where(v < GLASS_TRIM_V, 1.4, 0.6)) * np.exp(
        0.25 * _fractal(rng, 2.2, aspect=0.25))
    pitch = _seat_pitch()
    centre = np.abs((u_m % pitch) - pitch / 2)
    corner = 0.06  # rounded corners, m
    dx = np.maximum(centre - (HEADREST_W / 2 - corner), 0.0)
    dy = np.maximum(np.abs(v - HEADREST_V) * 0.9 - (HEADREST_HALF_V * 0.9 - corner), 0.0)  # 0.9 m pane
    seat = (np.hypot(dx, dy) < corner) | ((centre < SEAT_BACK_W / 2) & (v > SEAT_BACK_V))
    m = np.where(seat, 0.45 * (1.0 + 0.05 * _grain(rng, 1.5)), m)
    return np.repeat(m[..., None], 3, axis=2) * np.array([0.97, 1.0, 1.04])


# Car paint mirrors what stands around it: trees, façades and sky give light and dark streaks
# along a panel (about +-15 % of a panel's radiance, judged from photographs; no survey). A tile
# spans PAINT_TILE_M along and up the car.
PAINT_TILE_M = (4.0, 1.5)


def _paint(rng: np.random.Generator) -> np.ndarray:
    """Mirrored surroundings on a clear coat: soft streaks that run along the panel."""
    m = np.exp(0.15 * _fractal(rng, 2.0, aspect=0.2))
    return np.repeat(m[..., None], 3, axis=2)


def _segment_glyph(rng: np.random.Generator, rows: int, cols: int) -> np.ndarray:
    """A character-like mark: 4-6 of the seven segments of a display digit, strokes 12 % of the
    character's height thick (a letter or digit at the distances where plates are read by eye)."""
    g = np.zeros((rows, cols), bool)
    t = max(1, round(0.12 * rows))
    mid = rows // 2
    strokes = [(slice(0, t), slice(0, cols)), (slice(mid - t // 2, mid + t - t // 2), slice(0, cols)),
               (slice(rows - t, rows), slice(0, cols)), (slice(0, mid), slice(0, t)),
               (slice(0, mid), slice(cols - t, cols)), (slice(mid, rows), slice(0, t)),
               (slice(mid, rows), slice(cols - t, cols))]
    for i in rng.choice(7, size=int(rng.integers(4, 7)), replace=False):
        g[strokes[i]] = True
    return g


def _plates(rng: np.random.Generator) -> np.ndarray:
    """PLATES_PER_TILE plates, one per band of rows: white sheeting, a thin black rim, the blue
    EU band on the left, PLATE_CHARS black characters (simgen.render picks one band a car)."""
    band = SIZE // PLATES_PER_TILE
    m = np.ones((SIZE, SIZE, 3)) * (1.0 + 0.03 * _grain(rng))[..., None]
    px_u, px_v = SIZE / 0.52, band / 0.11  # texels per metre across and down a plate
    for k in range(PLATES_PER_TILE):
        r0 = k * band
        rim = max(1, round(0.004 * px_v))
        m[r0:r0 + rim], m[r0 + band - rim:r0 + band] = 0.05, 0.05
        m[r0:r0 + band, :rim], m[r0:r0 + band, SIZE - rim:] = 0.05, 0.05
        m[r0 + rim:r0 + band - rim, rim:round(0.04 * px_u)] = (0.06, 0.13, 0.5)
        rows, cols = round(0.075 * px_v), round(0.040 * px_u)
        top = r0 + (band - rows) // 2
        x = round(0.055 * px_u)
        step = (SIZE - round(0.012 * px_u) - x) / PLATE_CHARS
        for i in range(PLATE_CHARS):
            if i == 2 and rng.uniform() < 0.7:  # the gap between district and identifier
                continue
            c0 = round(x + i * step)
            m[top:top + rows, c0:c0 + cols][_segment_glyph(rng, rows, cols)] = 0.05
    return m


_MAKERS = {"asphalt": _asphalt, "marking": _marking, "paving": _paving, "concrete": _concrete,
           "grass": _grass, "soil": _concrete, "sand": _concrete, "foliage": _foliage, "bark": _bark,
           "planks": _planks, "metal": _metal, "plaster": _plaster, "brick": _brick, "roof": _roof}
# Which texture a scene material wears, by Material.name; façades choose plaster or brick by
# their colour (simgen.render). Materials not listed (actors, signs) stay flat.
OF_MATERIAL = {"asphalt": "asphalt", "marking": "marking", "sidewalk": "paving", "curb": "concrete",
               "verge": "grass", "forest_floor": "soil", "sand": "sand", "foliage": "foliage",
               "bark": "bark", "fence": "planks", "pole": "metal"}


# Actors' textures, seeded after the scenery's (adding one leaves every other tile as it was).
ACTOR_MAKERS = {"glass": _glass, "paint": _paint, "plate": _plates}
# Which texture an actor's part wears, by Material.name (simgen.render).
OF_ACTOR_MATERIAL = {"glass": "glass", "paint": "paint", "plate": "plate"}


def tile(kind: str, variant: int) -> np.ndarray:
    """(SIZE, SIZE, 3) uint8 multipliers / MAX_GAIN of one texture variant, normalised to a mean
    multiplier of 1 per channel."""
    return _made(kind, variant)[0]


def windows(kind: str, variant: int) -> tuple[Window, ...]:
    """The windows of one façade tile (none for the other kinds)."""
    return _made(kind, variant)[1]


@cache
def _made(kind: str, variant: int) -> tuple[np.ndarray, tuple[Window, ...]]:
    if kind in _MAKERS:
        index, make = sorted(_MAKERS).index(kind), _MAKERS[kind]
    elif kind in ACTOR_MAKERS:
        index, make = len(_MAKERS) + sorted(ACTOR_MAKERS).index(kind), ACTOR_MAKERS[kind]
    else:
        raise KeyError(f"no texture kind {kind!r} (known: {sorted(_MAKERS) + sorted(ACTOR_MAKERS)})")
    rng = np.random.default_rng([index, int(variant), 7919])
    made: list[Window] = []
    m = np.clip(make(rng, made) if make in (_plaster, _brick) else make(rng), 0.0, None)
    for _ in range(4):  # mean one per channel, after the clip at MAX_GAIN
        m = np.clip(m / m.reshape(-1, 3).mean(axis=0), 0.0, MAX_GAIN)
    return np.clip(np.round(m / MAX_GAIN * 255.0), 0, 255).astype(np.uint8), tuple(made)
