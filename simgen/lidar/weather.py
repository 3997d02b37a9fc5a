"""What fog and rain do to a LiDAR return: two-way extinction and spurious near returns.

Extinction. A return from range d is attenuated by exp(-2 * beta * d) (Beer-Lambert, both
ways), with beta = fog_extinction + the rain extinction below. The attenuated power then
meets the sensor's detection threshold (see LidarSpec.power), so weak, far returns vanish.

Rain extinction from the Marshall-Palmer drop-size distribution N(D) = N0 exp(-L D),
N0 = 8000 m^-3 mm^-1, L = 4.1 R^-0.21 mm^-1 (Marshall & Palmer 1948), with optical
extinction efficiency 2 (drops >> 905 nm):
    beta_rain = 2 * (pi/4) * integral D^2 N(D) dD = pi N0 / L^3 = 3.65e-4 * R^0.63  [1/m, R mm/h].

Fog scatter returns. Along each beam the first scattering event lies at an exponentially
distributed distance (rate beta_fog). Its echo is that of a Lambertian target of equivalent
reflectivity rho_fog = pi * (beta_fog / S) * dr, with lidar ratio S = 18 sr (water fog) and
the pulse half-length dr = 0.75 m (5 ns): a single-scattering lidar-equation estimate. The
echo is detected where its power clears the threshold, which confines it to the first metres
(the near clutter of Hahner et al., ICCV 2021, "Fog simulation on real LiDAR point clouds").
The sensor keeps the stronger of the scatter echo and the hard-target echo.

Rain clutter. Drops that return a detectable echo are met along a beam at rate
RAIN_CLUTTER_GAIN * beta_rain / 2 (geometric cross-section per volume times a gain for drops
anywhere in the beam footprint); their echo is a Lambertian target of rho = RAIN_DROP_RHO, so
only drops within a few metres are seen. The two constants are heuristic, set so that heavy
rain (10 mm/h) put a clutter return on about 1 % of the beams; document any recalibration. (With
road and leaf echoes read flat in incidence since, an echo from a drop beats the ray's own return
less often: 0.9 % instead of 1.25 % at 10 mm/h on urban world 0, results/lidar.md; the
constants are unchanged.)
"""

from __future__ import annotations

import numpy as np

from ..world import Weather

FOG_LIDAR_RATIO = 18.0  # sr
PULSE_HALF_LENGTH = 0.75  # m
RAIN_CLUTTER_GAIN = 5.0
RAIN_DROP_RHO = 0.002


def rain_extinction(rain_rate: float) -> float:
    """Two-way-free (one-way) extinction coefficient of rain, 1/m, at rain rate mm/h."""
    if rain_rate <= 0:
        return 0.0
    lam = 4.1 * rain_rate ** -0.21  # mm^-1
    return float(np.pi * 8000.0 / lam ** 3 * 1e-6)


def total_extinction(weather: Weather) -> float:
    return max(0.0, weather.fog_extinction) + rain_extinction(weather.rain_rate)


def fog_rho(weather: Weather) -> float:
    return float(np.pi * max(0.0, weather.fog_extinction) / FOG_LIDAR_RATIO * PULSE_HALF_LENGTH)


def clutter(weather: Weather, n: int, rng: np.random.Generator
            ) -> tuple[np.ndarray, np.ndarray]:
    """Per beam, the range (inf if none) and equivalent reflectivity of its weather echo.

    Fog and rain each draw a first-event distance; the nearer one is the candidate echo.
    Whether it is detected, and whether it beats the hard target, is the caller's business.
    """
    dist = np.full(n, np.inf)
    rho = np.zeros(n)
    beta_fog = max(0.0, weather.fog_extinction)
    if beta_fog > 0:
        dist = rng.exponential(1.0 / beta_fog, n)
        rho[:] = fog_rho(weather)
    rate_rain = RAIN_CLUTTER_GAIN * rain_extinction(weather.rain_rate) / 2.0
    if rate_rain > 0:
        d_rain = rng.exponential(1.0 / rate_rain, n)
        nearer = d_rain < dist
        dist = np.where(nearer, d_rain, dist)
        rho = np.where(nearer, RAIN_DROP_RHO, rho)
    return dist, rho
