"""The colour camera between the scene's light and the 8-bit image, in the order light meets it.

KITTI's colour cameras are Point Grey Flea2 FL2-14S3C: 1/2" Sony ICX267 CCDs behind a Bayer
colour filter array, whose frames the dataset publishes demosaiced, rectified and 8-bit. Each
step below is the physical one, with `simgen.world.CameraResponse` holding its strength:

1. exposure: automatic, the gain that brings the log-average luminance of the balanced image
   (step 8) to the key KEY of the white level (Reinhard et al. 2002, "Photographic tone
   reproduction for digital images", whose middle grey is 0.18), times 2 ** exposure_ev: a bright
   sky weighs no more than its share of the frame, and it and sunlit white saturate as they do in
   KITTI's frames;
2. white balance error: red and blue gains off by a log-normal error against green;
3. vignetting: illumination falling to `corner_illumination` at the image corner, as cos^4 of
   the field angle scaled to that value (lens data sheets give 50-85 % for compact lenses);
4. blur: a Gaussian of `blur_sigma_px` (output pixels) for the lens;
5. with `rectified` (the default), the image moves onto the raw sensor's pixels: the rendered
   image is a rectified one, and KITTI's raw colour frames have the lens's barrel distortion and
   a finer pitch (`rectification`);
6. the colour filter array: the filters' overlap mixes the channels (CROSSTALK), then each pixel
   keeps one channel (RGGB);
7. noise: shot noise of the collected electrons (Poisson, approximated by a Gaussian of
   variance equal to the count) and read noise, at `full_well_e` electrons for the white level;
8. colour balance: KITTI's gains on the raw channels (BALANCE), none below 1, clipped at the
   white level, so that what saturates comes out white as in KITTI's frames;
9. demosaicing (OpenCV's bilinear Bayer interpolation) on those pixels;
10. with `rectified`, the rectification: undistorted and resampled (bilinear) back to the output
   pixels, as KITTI's published frames were made from the raw ones;
11. the output curve to 8 bits, signal ** (1 / gamma): 2.2 is sRGB-like; machine-vision cameras
   such as the Flea2 can also put out the linear signal (gamma 1), which leaves shadows far
   darker. KITTI's frames are near linear (KEY and the default output gamma, 1.4).

Why 5 and 10 matter: the colour filter array and its demosaicing leave colour fringes one raw pixel
wide on every sharp edge. In KITTI's frames those pixels are 0.75 of an output pixel at the centre
and are then averaged by the rectification's interpolation; at the left and right edges, where the
barrel distortion packed the scene tighter, the rectification enlarges them (1.4 output pixels a
raw pixel), so KITTI's frames are softer at their sides than at their centre. Sampled at the
output's own pixels instead, every edge carried full-strength fringes two output pixels wide.
The two resamplings blur by 1/6 px^2 each in their own pixels (bilinear weights f, 1 - f over a
uniform f): the render onto the raw pixels (an artefact of rendering at the output's pitch) and the
rectification, 1/6 + 1/6 x 0.75^2 = 0.26 output px^2 at the centre, which the lens blur's ranges
in the scene specs leave out.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from .world import CameraResponse

GAMMA = 2.2  # the renderer's encoding of radiance (simgen.render), undone before exposure
# The tone of KITTI's frames, from the pixel statistics of its whole training set that detection
# code normalises inputs with: per-channel mean 93.8 / 98.8 / 95.9 and SD 78.8 / 80.1 / 81.2 (RGB,
# every pixel of every image). An sRGB-like curve (gamma 2.2) at any key leaves generated urban
# frames with an SD of at most 65 at a mean near 96: shadows lifted, sky and sunlit paint held
# back, as KITTI's frames are not (their shade is near black, their sky clips). The Flea2 also
# puts out a near-linear signal; the key and output gamma that give generated frames both of the
# set's figures are the defaults: the key 0.175 here and the output gamma 1.4
# (`CameraResponse.gamma`; `benchmarks/tone_curve.py --frames 120 --gammas 1.2 1.4`, 120 frames of
# scenes/urban.yaml: mean 95.3 and SD 79.9 at 0.17, 98.0 and 80.8 at 0.18, against 96.2 and 80.0;
# at gamma 1.2 no key gives both, SD 84.3 at a mean of 94.0; results/simgen.md). The canopies'
# colour (simgen.materials.canopy_reflectance) moves the fit: darker crowns and hedges lower the
# frames' log average, and with them in a single leaf's colour the same fit gives a key of 0.24 at
# gamma 1.2. The 11 real dev frames, a diagnosis only, have a pooled SD of 80.
KEY = 0.175
# The colour filters of a Bayer CCD overlap: each passes part of the light the other two peak on
# (the relative spectral responses in Sony's ICX-series data sheets: roughly 10-20 % off-band), so
# a camera that applies no colour-correction matrix records colours desaturated. Each channel here
# keeps 1 - 2 CROSSTALK of its own signal and CROSSTALK of each other's (rows sum to one: grey stays
# grey).
CROSSTALK = 0.15
# KITTI's colour balance, from the same whole-set statistic: its channel means 93.8 / 98.8 / 95.9
# put green above blue above red (G / R 1.053, B / R 1.022), a blue-green cast. Gains on the raw
# channels (R, G, B) after the colour filters and the noise, as a camera's white balance acts,
# none below 1 (what saturates the sensor comes out white, as in KITTI's frames). These give
# generated urban frames the set's two ratios (`benchmarks/tone_curve.py --frames 120 --balance`,
# scenes/urban.yaml: channel means 93.6 / 95.9 / 92.2 with no gains, 91.6 / 96.4 / 93.6 with these,
# at the key 0.165; the level is the key's); no real frame is read.
BALANCE = (1.0, 1.0516, 1.0751)
LOG_FLOOR = 1e-4  # keeps black pixels out of the log average (Reinhard's delta)
# An auto-exposure's range of gain and shutter, as factors of the reference exposure. The Flea2's
# shutter runs from 0.01 ms to beyond 60 ms and its gain from 0 to 24 dB (x16): a daylight
# exposure of about 1 ms leaves more than x64 for the night, where the near-linear output (gamma
# 1.2) needs it (a lit night street's log average is about 1/50 of the key: with x8 it came out
# at a mean grey of 7). Day frames need x1.7-5 (30 frames of scenes/urban_dr.yaml).
GAIN_LIMITS = (0.25, 64.0)


# KITTI's raw colour camera 02 and its rectification, from the raw data's calib_cam_to_cam.txt
# (2011_09_26, the calibration of the object benchmark's drives): S_02 1392 x 512 raw pixels,
# K_02 focal lengths 959.7910 / 956.9251 px, D_02 (k1, k2, p1, p2, k3) below (OpenCV's
# Brown-Conrady model), and the rectified image's P_rect_02 focal length 721.5377 px (S_rect_02
# 1242 x 375). The raw pitch is kept relative to the rig's own focal length, so a rig of another
# size or focal length gets KITTI's resampling; R_rect_02's rotation (under 1 degree) is left out.
RAW_FOCAL_RATIO = (959.7910 / 721.5377, 956.9251 / 721.5377)  # raw pixels a rectified one, x and y
RAW_DISTORTION = (-0.3691481, 0.1968681, 0.001353473, 0.0005677587, -0.06770705)
RAW_MARGIN = 2  # raw pixels kept round what the rectified frame reads (bilinear and demosaic reach)


LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 luminance of linear RGB


def _luminance(lin: np.ndarray) -> np.ndarray:
    return lin @ LUMA


def _vignetting(H: int, W: int, K: np.ndarray, corner: float) -> np.ndarray:
    """(H, W) relative illumination: cos^4 of the field angle, rescaled to `corner` at the
    farthest corner."""
    fall, most = _falloff(H, W, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))
    return 1.0 - fall * (1.0 - corner) / most


@lru_cache(maxsize=4)
def _falloff(H: int, W: int, fx: float, fy: float, cx: float, cy: float) -> tuple[np.ndarray, float]:
    """1 - cos^4 of each pixel's field angle, and its largest value (at least 1e-9): what the
    vignetting scales, the same for every frame of a camera."""
    u = (np.arange(W) - cx) / fx
    v = (np.arange(H) - cy) / fy
    cos4 = 1.0 / (1.0 + u[None, :] ** 2 + v[:, None] ** 2) ** 2
    return 1.0 - cos4, max(1.0 - float(cos4.min()), 1e-9)


def expose(lin: np.ndarray, K: np.ndarray, cam: CameraResponse, rng: np.random.Generator,
           key: float = KEY, balance: tuple[float, float, float] = BALANCE) -> np.ndarray:
    """Linear scene radiance (H, W, 3) float, 1 = a white surface at the reference light, to the
    camera's 8-bit RGB image; `key` is the auto-exposure's target and `balance` the gains on the
    raw channels (benchmarks/tone_curve.py tries others)."""
    H, W = lin.shape[:2]
    log_average = float(np.exp(np.log(LOG_FLOOR + _luminance(lin[::4, ::4])).mean()))
    # The meter reads the balanced image: the gains on the raw channels leave a grey's luminance
    # where the key puts it.
    gain = np.clip(key / (log_average * float(LUMA @ np.asarray(balance))), *GAIN_LIMITS) \
        * 2.0 ** cam.exposure_ev
    wb = np.exp(rng.normal(0.0, cam.white_balance_sd, 3) * np.array([1.0, 0.0, 1.0]))
    img = lin * (gain * wb)
    if cam.corner_illumination < 1.0:
        np.multiply(img, _vignetting(H, W, K, cam.corner_illumination)[..., None], out=img)
    if cam.blur_sigma_px > 0:
        img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), cam.blur_sigma_px)
    if cam.bayer:
        rect = rectification(H, W, tuple(np.asarray(K, float)[[0, 1, 0, 1], [0, 1, 2, 2]])) \
            if cam.rectified else None
        if rect is not None:
            img = cv2.remap(img.astype(np.float32), *rect.raw_from_output, cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REPLICATE)
            H, W = img.shape[:2]
        m = _crosstalk()  # each site records its filter's mix of the three channels (RGGB)
        raw = np.empty((H, W), np.float32)
        raw[0::2, 0::2] = img[0::2, 0::2] @ m[0]
        raw[0::2, 1::2] = img[0::2, 1::2] @ m[1]
        raw[1::2, 0::2] = img[1::2, 0::2] @ m[1]
        raw[1::2, 1::2] = img[1::2, 1::2] @ m[2]
        raw = np.clip(raw, 0.0, 1.0)
        raw = _balanced(_noisy(raw, cam, rng), balance)
        raw16 = np.round(raw * 65535.0).astype(np.uint16)
        # OpenCV names a pattern by the second row's first two pixels: RGGB is its "BayerBG".
        rgb16 = cv2.cvtColor(raw16, cv2.COLOR_BayerBG2RGB)
        if rect is not None:
            rgb16 = cv2.remap(rgb16, *rect.output_from_raw, cv2.INTER_LINEAR)
        return _output_table(cam.gamma)[rgb16]
    img = np.clip(img, 0.0, 1.0).astype(np.float32)
    return _output_curve(_noisy(img, cam, rng) * np.asarray(balance, np.float32), cam.gamma)


@dataclass(frozen=True)
class Rectification:
    """The resampling between a rectified image and its raw camera's pixels, as cv2.remap maps
    (fixed point, 1/32 pixel): `raw_from_output` gives every raw pixel its place in the rectified
    image (how the raw image is drawn from the render), `output_from_raw` every rectified pixel
    its place on the raw sensor (the rectification itself). The first map's shape is the
    simulated raw frame's (H, W)."""

    raw_from_output: tuple[np.ndarray, np.ndarray]
    output_from_raw: tuple[np.ndarray, np.ndarray]


def distort(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalised undistorted image coordinates to distorted ones through RAW_DISTORTION
    (OpenCV's model: radial k1 r^2 + k2 r^4 + k3 r^6, tangential p1, p2)."""
    k1, k2, p1, p2, k3 = RAW_DISTORTION
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y)


def undistort(xd: np.ndarray, yd: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of `distort` by Newton's method on the 2 x 2 Jacobian, from the distorted
    point itself (quadratic convergence wherever the distortion stays monotone, out to r 1.2:
    the simulated raw frame's farthest pixel lies at r 0.99 for KITTI's rectified frame)."""
    k1, k2, p1, p2, k3 = RAW_DISTORTION
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        fx = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)  # distort(x, y), its r2 reused
        fy = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x  # d fx / dx
        b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y  # d fx / dy = d fy / dx
        d = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x  # d fy / dy
        ex, ey = fx - xd, fy - yd
        det = a * d - b * b
        x = x - (d * ex - b * ey) / det
        y = y - (a * ey - b * ex) / det
    return x, y


@lru_cache(maxsize=4)
def rectification(H: int, W: int, f_c: tuple[float, float, float, float]) -> Rectification:
    """The raw camera behind a rectified H x W image of focal lengths and principal point
    f_c = (fx, fy, cx, cy): RAW_FOCAL_RATIO times its focal lengths, distorted by RAW_DISTORTION,
    its frame the rectified image's footprint plus RAW_MARGIN."""
    fx, fy, cx, cy = f_c
    rx, ry = RAW_FOCAL_RATIO
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    xd, yd = distort((u - cx) / fx, (v - cy) / fy)
    px, py = xd * (rx * fx), yd * (ry * fy)  # raw pixels about the raw principal point
    ox, oy = RAW_MARGIN - np.floor(px.min()), RAW_MARGIN - np.floor(py.min())
    raw_w = int(np.ceil(px.max() + ox)) + RAW_MARGIN + 1
    raw_h = int(np.ceil(py.max() + oy)) + RAW_MARGIN + 1
    raw_w += raw_w % 2  # whole RGGB cells
    raw_h += raw_h % 2
    i, j = np.meshgrid(np.arange(raw_w, dtype=np.float64), np.arange(raw_h, dtype=np.float64))
    x, y = undistort((i - ox) / (rx * fx), (j - oy) / (ry * fy))
    back = cv2.convertMaps((x * fx + cx).astype(np.float32), (y * fy + cy).astype(np.float32),
                           cv2.CV_16SC2)
    forward = cv2.convertMaps((px + ox).astype(np.float32), (py + oy).astype(np.float32), cv2.CV_16SC2)
    return Rectification(back, forward)


@lru_cache(maxsize=1)
def _crosstalk() -> np.ndarray:
    """(3, 3) float32 mixing of the linear RGB signal by the overlapping colour filters."""
    return ((1 - 3 * CROSSTALK) * np.eye(3) + CROSSTALK).astype(np.float32)


def _output_curve(signal: np.ndarray, gamma: float) -> np.ndarray:
    """Linear float32 signal (1 = white level) to 8-bit output values."""
    return np.round(np.clip(signal, 0.0, 1.0) ** (1.0 / gamma) * 255.0).astype(np.uint8)


@lru_cache(maxsize=8)
def _output_table(gamma: float) -> np.ndarray:
    """The 8-bit output of every demosaiced 16-bit value: one lookup per pixel instead of a
    float32 power (the same arithmetic per value, so the same bytes)."""
    return _output_curve(np.arange(65536, dtype=np.uint16).astype(np.float32) / 65535.0, gamma)


def _balanced(raw: np.ndarray, balance: tuple[float, float, float]) -> np.ndarray:
    """The RGGB mosaic times each site's channel gain, clipped to the white level again; in place
    (`raw` is the noise step's own array)."""
    if balance == (1.0, 1.0, 1.0):
        return raw
    np.multiply(raw, _gain_mosaic(*raw.shape, balance), out=raw)
    return np.minimum(raw, np.float32(1.0), out=raw)


@lru_cache(maxsize=4)
def _gain_mosaic(H: int, W: int, balance: tuple[float, float, float]) -> np.ndarray:
    """(H, W) float32 gain of each RGGB site: one contiguous product instead of four strided."""
    r, g, b = (np.float32(v) for v in balance)
    gains = np.empty((H, W), np.float32)
    gains[0::2, 0::2], gains[0::2, 1::2], gains[1::2, 0::2], gains[1::2, 1::2] = r, g, g, b
    return gains


def _noisy(signal: np.ndarray, cam: CameraResponse, rng: np.random.Generator) -> np.ndarray:
    """Shot and read noise of a linear signal in [0, 1] (1 = full well), clipped to [0, 1]."""
    if cam.full_well_e <= 0:
        return signal
    sd = signal * cam.full_well_e  # electrons, then the noise's sd on the signal's scale (in place)
    sd += cam.read_noise_e ** 2
    np.sqrt(sd, out=sd)
    sd /= cam.full_well_e
    noisy = rng.standard_normal(signal.shape, dtype=np.float32)
    noisy *= sd
    noisy += signal
    return np.clip(noisy, 0.0, 1.0, out=noisy)
