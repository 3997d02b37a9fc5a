"""What a rotating multi-beam LiDAR is: beam table, firing pattern, range limits, error model.

Presets come from the sensors' datasheets (elevation tables, angular steps, ranges, accuracy). Every field is plain data
(tuples, floats), so a spec is hashable and the ray table it implies is computed once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from kitti.rings import HDL64E_ELEVATIONS  # KITTI's own sensor: its table lives in kitti

HDL32E_ELEVATIONS = tuple(round(10.67 - i * (10.67 + 30.67) / 31.0, 4) for i in range(32))

VLP32C_ELEVATIONS = tuple(sorted((
    -25.0, -15.639, -11.31, -8.843, -7.254, -6.148, -5.333, -4.667, -4.0, -3.667, -3.333, -3.0,
    -2.667, -2.333, -2.0, -1.667, -1.333, -1.0, -0.667, -0.333, 0.0, 0.333, 0.667, 1.0, 1.333,
    1.667, 2.333, 3.333, 4.667, 7.0, 10.333, 15.0), reverse=True))

VLP16_ELEVATIONS = tuple(float(15 - 2 * i) for i in range(16))


@dataclass(frozen=True)
class LidarSpec:
    """One sensor model. Rings are numbered from the top beam (ring 0, highest elevation) down,
    the order of KITTI's .bin files.

    Detection follows a lidar equation for an extended target,
    P = rho_eff * exp(-2 * beta * d) * (d_ref / d) ** range_exponent, with rho_eff the surface's
    reading at its incidence (reflectivity * cos(incidence) ** k for the material's exponent k,
    times the two-way loss through any glass on the way; see scan.py), and a return is detected
    when P >= the power of a 10 % target at normal incidence at `dark_range` in clear air.
    `range_exponent` is fitted to two datasheet points (HDL-64E S2: 50 m on 10 % pavement,
    120 m on 80 % cars and foliage), so dark, far and grazing surfaces vanish first. `max_range`
    is a hard cut-off on top of that (the sensor reports nothing farther), which range sweeps lower.

    The reflectance channel (scan.py's module docstring has the model) is KITTI's HDL-64E as
    measured on the real scans by `benchmarks/lidar_reflectance_stats.py` (every frame of
    the real set pooled; section numbers below refer to its output). The other presets share
    these figures: no real scans of theirs are at hand.
    """

    name: str
    elevations_deg: tuple[float, ...]  # per beam, ring 0 first (descending)
    azimuth_step_deg: float
    rotation_hz: float = 10.0
    min_range: float = 0.9
    max_range: float = 120.0
    # vehicle-from-LiDAR mount (x fwd, y left, z up from the road under the ego origin): the
    # scene generator places the onboard rig with it (simgen.sample). scan() uses
    # world.lidar_pose, so a rescan keeps the recorded pose and with it the calibration.
    mount_xyz: tuple[float, float, float] = (0.0, 0.0, 1.73)
    noise_sigma: float = 0.015  # per-ray Gaussian range noise (m)
    bias_sigma: float = 0.01  # fixed per-laser range bias (m), drawn once per sensor unit
    # the sensor unit: seeds the per-laser biases, gains, zero shares and drop-out rates, constant
    # across frames
    unit_seed: int = 0
    lasers: tuple[int, ...] = ()  # the unit's laser number per beam (empty: 0, 1, 2, ...)
    # Per beam: how far the laser's beam runs above the sensor origin, perpendicular to the beam in
    # its vertical plane (Velodyne's per-laser `vertOffsetCorrection`): a return lies at
    # source + range x direction. Empty: every beam starts at the origin.
    source_offsets_m: tuple[float, ...] = ()
    # Random loss of a detected return, mean over the lasers (a value kept from before; the lowest
    # lasers' fixed empty sectors on KITTI's scans are its car's, `platform.py`, not this loss).
    dropout: float = 0.02
    # Spread (sd) of the per-laser loss rate around `dropout`, drawn once per unit: the lasers of
    # KITTI's lower block, which all see road or an obstacle at every azimuth, return within
    # 0.5 % (sd) of their elevation neighbours' counts (section 5).
    dropout_sigma: float = 0.005
    dark_range: float = 50.0  # range on a 10 % target (datasheet)
    bright_range: float = 120.0  # range on a rho_bright target (datasheet)
    rho_bright: float = 0.8
    detection: bool = True  # False: keep every hit within range (no power threshold)
    # Reflectance channel. KITTI writes it as float32(k / 100), k = 0..99: the step is 0.01 and
    # the largest value 0.99, which 0.19 % of returns read (saturated) (section 1).
    refl_step: float = 0.01
    refl_max: float = 0.99
    # Readings below this read 0: after 16.5 % of returns at 0.00, 0.01 and 0.02 hold 0.01 % and
    # 0.07 % against 0.54 % and 1.61 % for 0.03 and 0.04 (section 1): the floor lies between.
    refl_floor: float = 0.025
    # A return whose echo power is below refl_floor_power x the detection threshold reads 0
    # (the unit's intensity clamps at its calibrated minimum). Measured on KITTI's road: half its
    # returns read 0 at 37 m, where the floor meets
    # the road's median nonzero reading at 4-20 m (0.24): 0.24 / 0.1 * (50 / 37) ** 2.375 = 4.89
    # (section 3).
    refl_floor_power: float = 4.89
    # Whether a return reads 0 there is decided on a scatter draw of its own, not the reading's:
    # KITTI's road reads 0 on 12 % of its returns at 4-20 m and 44 % at 30-40 m, yet its nonzero
    # median stays 0.24-0.26; the reading's own draw would leave its bright survivors, 0.28 at
    # 30-40 m and 0.41 at 40-50 m (section 7).
    # The reading is range-compensated out to `compensation_range` only; a farther return reads
    # rho_eff * (compensation_range / d) ** range_exponent, as its echo power falls. KITTI's road
    # reads a nonzero median of 0.17 at 40-50 m and 0.155 at 50-60 m where full compensation
    # gives 0.28 and 0.30. Fitted (least squares in log, 0.5 m steps) to the pooled road's nonzero
    # medians at 20-81 m through this reading model (section 7); it undershoots the 29 nonzero
    # road readings beyond 60 m (0.07 against 0.19).
    compensation_range: float = 36.0
    # Per-laser gain of the reading, log-normal with median 1, drawn once per unit: sd of
    # log(laser's median road reading / all lasers' median) over 45 lasers (section 4).
    gain_sigma: float = 0.225
    # Each laser reads 0 on a fixed share of its returns whatever their echo (the range is
    # reported, the intensity is not): log-normal over the lasers, drawn once per unit. On KITTI's
    # road at 4-20 m the share of one laser in one frame has median 0.038 and log-sd 1.55 (half
    # the distance between the 16th and 84th percentiles of the log) over 472 laser-frames, from
    # 0.2 % to 46 % (5th-95th percentile); consistent within a drive, different between drives
    # (the unit's intensity calibration), mean 10 % (section 4).
    zero_share_median: float = 0.038
    zero_share_sigma: float = 1.55
    # Per-return scatter of the reading (log-logistic, this robust sd of the log: 1.4826 x its
    # median absolute deviation): one laser's readings on road at 4-20 m in one frame, robust sd
    # of the log, median over 477 laser-frames
    # (section 4). It lumps the sensor's amplitude noise with the pavement's texture, which the
    # scenes' uniform materials lack.
    reading_sigma: float = 0.31
    # Glass and porous materials pass rays on (False: every surface is opaque, the first hit returns)
    transmission: bool = True
    motion: bool = True  # per-ray time: ego and actor motion during the sweep
    weather: bool = True  # apply world.weather (fog, rain)

    def __post_init__(self) -> None:
        el = np.asarray(self.elevations_deg, dtype=float)
        if el.ndim != 1 or len(el) == 0:
            raise ValueError(f"LidarSpec {self.name!r}: elevations_deg must be a non-empty list")
        if np.any(np.diff(el) >= 0):
            raise ValueError(f"LidarSpec {self.name!r}: elevations_deg must be strictly "
                             "descending (ring 0 = top beam)")
        if len(el) > 255:
            raise ValueError(f"LidarSpec {self.name!r}: at most 255 beams (ring is uint8)")
        if self.lasers and len(self.lasers) != len(el):
            raise ValueError(f"LidarSpec {self.name!r}: lasers needs one entry per beam")
        if self.source_offsets_m and len(self.source_offsets_m) != len(el):
            raise ValueError(f"LidarSpec {self.name!r}: source_offsets_m needs one entry per beam")
        if not 0 < self.azimuth_step_deg <= 10:
            raise ValueError(f"LidarSpec {self.name!r}: azimuth_step_deg must be in (0, 10]")
        if not 0 <= self.min_range < self.max_range:
            raise ValueError(f"LidarSpec {self.name!r}: need 0 <= min_range < max_range")
        if self.rotation_hz <= 0:
            raise ValueError(f"LidarSpec {self.name!r}: rotation_hz must be > 0")
        if not 0 <= self.dropout < 1 or self.dropout_sigma < 0:
            raise ValueError(f"LidarSpec {self.name!r}: dropout must be in [0, 1) and "
                             "dropout_sigma >= 0")
        if not (0 < self.refl_step and 0 < self.refl_max <= 1 and 0 <= self.refl_floor
                and self.refl_floor_power >= 0 and self.compensation_range > 0 and self.gain_sigma >= 0
                and self.reading_sigma >= 0 and 0 <= self.zero_share_median <= 1
                and self.zero_share_sigma >= 0):
            raise ValueError(f"LidarSpec {self.name!r}: need refl_step > 0, refl_max in (0, 1], "
                             "zero_share_median in [0, 1], compensation_range > 0 and refl_floor, "
                             "refl_floor_power, gain_sigma, reading_sigma, zero_share_sigma >= 0")
        if not 0 < self.dark_range < self.bright_range or not 0.1 < self.rho_bright <= 1:
            raise ValueError(f"LidarSpec {self.name!r}: need 0 < dark_range < bright_range and "
                             "0.1 < rho_bright <= 1")

    @property
    def beams(self) -> int:
        return len(self.elevations_deg)

    @property
    def columns(self) -> int:
        """Firings per revolution per laser."""
        return int(round(360.0 / self.azimuth_step_deg))

    @property
    def period(self) -> float:
        return 1.0 / self.rotation_hz

    @property
    def range_exponent(self) -> float:
        """gamma with rho_bright / bright_range**gamma == 0.1 / dark_range**gamma."""
        return math.log(self.rho_bright / 0.1) / math.log(self.bright_range / self.dark_range)

    def power(self, rho_eff: np.ndarray, dist: np.ndarray, beta: float = 0.0) -> np.ndarray:
        """Received power relative to the detection threshold (detected where >= 1)."""
        g = self.range_exponent
        rel = rho_eff / 0.1 * (self.dark_range / np.maximum(dist, 1e-3)) ** g
        return rel * np.exp(-2.0 * beta * dist) if beta > 0 else rel

    def threshold(self, dist: np.ndarray) -> np.ndarray:
        """The echo strength rho_eff that a return at `dist` needs in clear air to be detected,
        0.1 * (dist / dark_range) ** range_exponent (float32 for a float32 `dist`)."""
        g = self.range_exponent
        need = np.power(dist, np.float32(g))
        need *= np.float32(0.1 / self.dark_range ** g)
        return need

    def detected(self, rho_eff: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """power(rho_eff, dist) >= 1 in clear air, in fewer passes (the scan's hot path)."""
        return rho_eff >= self.threshold(dist)

    def _unit_table(self, stream: int, scale: float) -> np.ndarray:
        """One standard-normal draw per laser number of this unit (times `scale`), for this
        spec's beams; a beam subset (`beams=N`) keeps the values of the lasers it keeps."""
        lasers = np.asarray(self.lasers or range(self.beams), dtype=np.int64)
        seed = self.unit_seed if stream == 0 else (self.unit_seed, stream)
        table = np.random.default_rng(seed).normal(0.0, scale, max(256, int(lasers.max()) + 1))
        return table[lasers]

    def laser_biases(self) -> np.ndarray:
        """The unit's fixed per-laser range biases (m), the same for every frame it scans."""
        return self._unit_table(0, self.bias_sigma)

    def laser_gains(self) -> np.ndarray:
        """The unit's fixed per-laser reading gains (log-normal, median 1)."""
        return np.exp(self._unit_table(1, self.gain_sigma))

    def laser_dropouts(self) -> np.ndarray:
        """The unit's fixed per-laser loss rates: `dropout` +- `dropout_sigma`, in [0, 0.5]."""
        if self.dropout <= 0:
            return np.zeros(self.beams)
        return np.clip(self.dropout + self._unit_table(2, self.dropout_sigma), 0.0, 0.5)

    def laser_zero_shares(self) -> np.ndarray:
        """The unit's fixed per-laser shares of returns that read 0 (log-normal, capped at 1)."""
        if self.zero_share_median <= 0:
            return np.zeros(self.beams)
        return np.minimum(self.zero_share_median * np.exp(self._unit_table(3, self.zero_share_sigma)),
                          1.0)

    def ideal(self) -> LidarSpec:
        """The same geometry with every error source off: exact ranges, all returns kept, every
        surface opaque (the first hit returns), the reading without per-laser gains, scatter
        or zero readings (still floored and quantised as KITTI writes it)."""
        return replace(self, noise_sigma=0.0, bias_sigma=0.0, dropout=0.0, motion=False,
                       weather=False, detection=False, transmission=False, gain_sigma=0.0,
                       reading_sigma=0.0, zero_share_median=0.0)


def _subsample(elev: tuple[float, ...], beams: int, name: str) -> tuple[float, ...]:
    n = len(elev)
    if beams == n:
        return elev
    if beams <= 0 or beams > n or n % beams:
        raise ValueError(f"preset {name!r} has {n} beams; beams={beams} must divide {n} "
                         f"(keeps every {n}//beams-th laser, like reduce-beams); use the "
                         "'uniform' preset for any other beam count")
    return elev[:: n // beams]


def _hdl64e_source_offsets(elevations: tuple[float, ...]) -> tuple[float, ...]:
    """Where the HDL-64E's beams start: each block's lasers sit behind their own lens, so a
    beam runs about 0.2 m (upper block) or 0.11 m (lower block) above the unit's origin, a little
    more for the higher lasers of a block. A published HDL-64E S2.1 calibration (Velodyne's
    db.xml of one unit, shipped with the ROS velodyne driver as `64e_s2.1-sztaki.yaml`) gives
    vertOffsetCorrection 0.2097 m at +2.49 deg and 0.1955 m at -8.77 deg (upper block), 0.1215 m
    at -11.52 deg and 0.1054 m at -24.85 deg (lower block): linear in the elevation within a
    block, 1.2-1.3 mm per degree. Seen from the origin, the lowest laser's road returns at 4 m
    then lie at about -23.7 deg rather than its -24.9 deg, as KITTI's do (their lowest ring's
    median elevation is -23.2 to -23.6 deg)."""
    upper = len(elevations) // 2
    out = []
    for i, e in enumerate(elevations):
        if i < upper:
            out.append(0.1955 + (0.2097 - 0.1955) * (e + 8.77) / (2.49 + 8.77))
        else:
            out.append(0.1054 + (0.1215 - 0.1054) * (e + 24.85) / (24.85 - 11.52))
    return tuple(round(v, 5) for v in out)


# The real sensors' elevation tables and datasheet figures (Velodyne HDL-64E S2, HDL-32E, VLP-32C,
# VLP-16 manuals).
_REAL = {
    "hdl64e": LidarSpec("hdl64e", HDL64E_ELEVATIONS, azimuth_step_deg=0.18, max_range=120.0,
                        noise_sigma=0.015, bias_sigma=0.01, dark_range=50.0, bright_range=120.0,
                        source_offsets_m=_hdl64e_source_offsets(HDL64E_ELEVATIONS)),
    "hdl32e": LidarSpec("hdl32e", HDL32E_ELEVATIONS, azimuth_step_deg=0.16, max_range=100.0,
                        noise_sigma=0.015, bias_sigma=0.01, dark_range=40.0, bright_range=100.0),
    "vlp32c": LidarSpec("vlp32c", VLP32C_ELEVATIONS, azimuth_step_deg=0.2, max_range=200.0,
                        noise_sigma=0.02, bias_sigma=0.015, dark_range=80.0, bright_range=200.0),
    "vlp16": LidarSpec("vlp16", VLP16_ELEVATIONS, azimuth_step_deg=0.2, max_range=100.0,
                       noise_sigma=0.02, bias_sigma=0.015, dark_range=40.0, bright_range=100.0),
}
PRESETS = (*_REAL, "uniform")


def preset(name: str, beams: int | None = None, max_range: float | None = None,
           fov_deg: tuple[float, float] = (2.0, -24.9)) -> LidarSpec:
    """A named sensor.

    On a real preset `beams=N` keeps every (native/N)-th laser of its table (rings 0, k, 2k, ...),
    exactly what `testbed reduce-beams` does to a recorded scan, so a rescan with fewer beams and
    a reduced scan are the same sensor. N must divide the native count. `uniform` spaces
    `beams` (default 64) lasers evenly over `fov_deg` (top, bottom), with the HDL-64E's firing
    rate, range and error model.
    """
    key = name.lower().replace("-", "").replace("_", "")
    if key in _REAL:
        spec = _REAL[key]
    elif key == "uniform":
        n = 64 if beams is None else int(beams)
        top, bottom = float(fov_deg[0]), float(fov_deg[1])
        if n < 1 or not top > bottom:
            raise ValueError(f"uniform preset: need beams >= 1 and fov top > bottom, got "
                             f"{n}, {fov_deg}")
        elev = (top,) if n == 1 else tuple(float(e) for e in np.linspace(top, bottom, n))
        spec = LidarSpec(f"uniform{n}", elev, azimuth_step_deg=0.18, max_range=120.0)
        beams = None
    else:
        raise ValueError(f"unknown LiDAR preset {name!r}; choose {', '.join(PRESETS[:-1])} "
                         f"or {PRESETS[-1]}")
    if beams is not None and beams != spec.beams:
        elev = _subsample(spec.elevations_deg, int(beams), spec.name)
        step = spec.beams // len(elev)
        spec = replace(spec, name=f"{spec.name}-{beams}", elevations_deg=elev,
                       lasers=tuple(range(0, spec.beams, step)),
                       source_offsets_m=spec.source_offsets_m[::step])
    if max_range is not None:
        spec = replace(spec, max_range=float(max_range))
    return spec



def sensor_record(preset_name: str, beams: int | None, max_range: float | None) -> dict:
    """The sensor as a dataset's meta and manifest record it: the preset, the beam count it scans
    with (always a number, so a reader never needs this table) and the range asked for."""
    return {"preset": preset_name, "beams": preset(preset_name, beams=beams).beams,
            "max_range": max_range}
