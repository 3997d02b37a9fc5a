"""What the weather and the sensor do to the rendered image.

Fog follows the world's one weather model (the LiDAR uses the same beta): Koschmieder's law
I' = I exp(-beta d) + A (1 - exp(-beta d)), with d the ray length from the depth image and A
the airlight of the time of day; the sky (no surface) becomes A. Rain draws streaks whose
number grows with the rain rate and whose slant is atan(wind / 7 m/s), the fall speed of a
typical 2 mm drop (not drawn on thermal images); rain's own extinction is left to the LiDAR
model. The sensor looks are
emulations (003): night vision = luminance with automatic gain, photon noise, green phosphor
and a tube vignette; thermal = the renderer's temperature image, blurred, with sensor noise.
The normal colour camera's own response (exposure, white balance, vignetting, blur, colour
filter array and noise) is simgen.camera, applied last.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from .camera import GAMMA, expose
from .world import CameraResponse, Light, Weather

AIRLIGHT = {"day": (0.78, 0.80, 0.83), "dusk": (0.52, 0.45, 0.42), "night": (0.04, 0.04, 0.05)}
DROP_FALL_SPEED = 7.0  # m/s
STREAKS_PER_MM_H = 40  # streaks in a 1242 x 375 frame per mm/h


def ray_length(depth: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Distance along each pixel's ray from its z-depth (inf where depth is 0: the sky)."""
    H, W = depth.shape
    u = (np.arange(W) - K[0, 2]) / K[0, 0]
    v = (np.arange(H) - K[1, 2]) / K[1, 1]
    scale = np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2)
    return np.where(depth > 0, depth * scale, np.inf)


def fog(img: np.ndarray, depth: np.ndarray, K: np.ndarray, beta: float, time: str) -> np.ndarray:
    t = np.exp(-beta * ray_length(depth, K))[..., None]
    return img * t + np.asarray(AIRLIGHT[time]) * (1.0 - t)


def rain(img: np.ndarray, rate: float, wind: float, time: str, rng: np.random.Generator) -> np.ndarray:
    H, W = img.shape[:2]
    n = int(round(rate * STREAKS_PER_MM_H * W * H / (1242 * 375)))
    if n == 0:
        return img
    layer = np.zeros((H, W), np.float32)
    angle = np.arctan2(wind, DROP_FALL_SPEED)
    length = rng.uniform(8.0, 28.0, n) * H / 375.0
    x0, y0 = rng.uniform(-0.2 * W, 1.2 * W, n), rng.uniform(-0.1 * H, H, n)
    x1, y1 = x0 + length * np.sin(angle), y0 + length * np.cos(angle)
    for a, b, c, d, s in zip(x0, y0, x1, y1, rng.uniform(0.15, 0.35, n)):
        cv2.line(layer, (int(a), int(b)), (int(c), int(d)), float(s), 1, cv2.LINE_AA)
    layer = cv2.GaussianBlur(layer, (3, 3), 0)[..., None]
    brightness = 0.9 if time == "day" else 0.5
    return img * (1.0 - layer) + brightness * layer


def night_vision(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    lum = img @ np.array([0.299, 0.587, 0.114])
    gain = 0.85 / max(float(np.percentile(lum, 99.5)), 0.02)
    v = np.clip(lum * gain, 0.0, 1.0)
    v = v + rng.normal(0.0, 0.04 + 0.05 * np.sqrt(v))
    v = cv2.GaussianBlur(v.astype(np.float32), (3, 3), 0)
    H, W = v.shape
    yy, xx = np.mgrid[0:H, 0:W]
    r2 = ((xx - W / 2) / (0.6 * W)) ** 2 + ((yy - H / 2) / (0.6 * W)) ** 2
    v = np.clip(v * np.clip(1.2 - r2, 0.0, 1.0), 0.0, 1.0)
    return v[..., None] * np.array([0.25, 1.0, 0.35])


def thermal(img: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    v = img.mean(axis=2).astype(np.float32)
    v = cv2.GaussianBlur(v, (5, 5), 1.2)
    v = np.clip(v + rng.normal(0.0, 0.015, v.shape), 0.0, 1.0)
    return np.repeat(v[..., None], 3, axis=2)


def apply_look(color: np.ndarray, depth: np.ndarray, K: np.ndarray, weather: Weather, light: Light,
               sensor: str, rng: np.random.Generator, headroom: float = 1.0,
               camera: CameraResponse | None = None) -> np.ndarray:
    """The final uint8 RGB image of a frame. `color` is the renderer's gamma-encoded image of
    linear radiance / `headroom`; with a `camera`, the normal sensor's image goes through it
    (simgen.camera), else it is clipped and quantised as rendered."""
    clear = not (weather.fog_extinction > 0 or weather.rain_rate > 0)
    if camera is not None and sensor not in ("night_vision", "thermal") and clear \
            and color.dtype == np.uint8:  # the common frame: one table lookup per pixel
        return expose(rendered_radiance(color, headroom), K, camera, rng)
    img = _encoded(color, headroom)
    if weather.fog_extinction > 0:
        img = fog(img, depth, K, weather.fog_extinction, "night" if sensor == "thermal" else light.time)
    if weather.rain_rate > 0 and sensor != "thermal":  # long-wave infrared hardly sees streaks
        img = rain(img, weather.rain_rate, weather.wind, light.time, rng)
    if sensor == "night_vision":
        img = night_vision(np.clip(img, 0.0, 1.0), rng)
    elif sensor == "thermal":
        img = thermal(img, rng)
    elif camera is not None:
        return expose(_radiance(img), K, camera, rng)
    return np.clip(np.round(img * 255.0), 0, 255).astype(np.uint8)


def _encoded(color: np.ndarray, headroom: float) -> np.ndarray:
    """The renderer's colours as float64 gamma-encoded radiance (1 = white at the reference light)."""
    return color.astype(np.float64) / 255.0 * headroom ** (1 / GAMMA)


def _radiance(img: np.ndarray) -> np.ndarray:
    """Gamma-encoded radiance to linear radiance."""
    return np.clip(img, 0.0, None) ** GAMMA


def rendered_radiance(color: np.ndarray, headroom: float) -> np.ndarray:
    """The linear radiance of the renderer's uint8 colours (what `expose` takes)."""
    return _radiance_table(headroom)[color]


@lru_cache(maxsize=8)
def _radiance_table(headroom: float) -> np.ndarray:
    """The linear radiance of each 8-bit rendered value: one lookup per pixel instead of a
    float64 power (the same arithmetic per value, so the same bits)."""
    return _radiance(_encoded(np.arange(256, dtype=np.uint8), headroom))
