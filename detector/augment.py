"""Training-time augmentation: mosaic, scale/translate, horizontal flip, HSV colour jitter, the
two Mixup variants of 004 (plain: lambda ~ Beta(8, 8), both images' boxes kept; thresholded:
mixed only when no box of one image overlaps a box of the other at IoU >= 0.4), and a
photometric set for sim-to-real transfer (structured domain randomization: the detector is
trained on rendered images and must work on real KITTI photographs).

Photometric set (`AugmentConfig.photometric`; each op with its own probability per sample, the
ranges below are the defaults). It runs on the final sample (after Mixup), in the order a camera
would: scene (cut-out occluders) -> optics (blur) -> sensor (noise) -> ISP (white balance,
contrast, gamma, greyscale) -> compression (JPEG). No op changes geometry: boxes are unchanged.

- cut-out (p 0.25): 1-3 rectangles 5-30% of the image height tall, aspect 1:3..3:1, filled with
  one random grey or uniform noise (random erasing / occluders the renderer does not have). A
  rectangle is only placed where every labelled box stays at most `cutout_max_cover` (0.5)
  covered by all rectangles together; one that would cover more is redrawn (10 tries, then left
  out). We avoid rather than drop: a box dropped at, say, 60% cover still shows 40% of its
  object, which would then be trained as background - KITTI labels (and scores) heavily occluded
  objects, so the detector must fire on them; keeping every box while capping its cover at a half
  teaches partial occlusion without ever labelling pure grey as a car.
- white balance (p 0.5): per-channel gain in [1 - 0.1, 1 + 0.1] (auto white balance of real
  cameras misses by several per cent; KITTI frames have visible colour casts).
- contrast (p 0.5): factor in [0.75, 1.25] about the mean luminance; gamma (p 0.5): log-uniform
  in [1/1.3, 1.3] (tone curves differ between renderer and camera ISP).
- greyscale (p 0.05): KITTI's rig itself has two greyscale cameras; rare, so colour statistics
  are barely shifted but the network does not lean on colour alone.
- Gaussian blur (p 0.3): sigma in [0.3, 1.5] px at KITTI resolution (1242 px wide), scaled to
  the working width: defocus, lens softness and the Bayer demosaic of a 1.4 MP camera against
  the renderer's crisp, aliased edges.
- motion blur (p 0.1): a line kernel 2-6 KITTI px long at a random angle (10 Hz capture at
  speed, camera shake).
- sensor noise (p 0.5): Poisson-Gaussian (heteroscedastic) noise in linear intensity: the image
  is decoded through the sRGB curve to L in [0, 1], L + n with var(n) = L / FW + (R / FW)^2, and
  encoded again. FW, the full well in electrons that the 8-bit range spans after analogue gain,
  is log-uniform in [3000, 20000]; R, the read noise, uniform in [2, 8] e-. Machine-vision
  sensors (EMVA 1288 sheets, e.g. KITTI's Sony ICX267 CCD class) have full wells of about
  6-20 ke- and read noise of a few e-; gain up to about 6 dB lowers the effective full well. That
  gives a standard deviation of about 1-2.5 DN (8-bit) at mid grey and up to about 5 DN in the
  shadows, as on real frames.
  Channels and pixels are independent (no demosaic correlation).
- JPEG (p 0.2): re-encoded at quality 50-95 (cv2.imencode): compression blocking/ringing. KITTI
  itself is stored as PNG, so this is kept rare; it mostly suppresses renderer-specific high
  frequencies.
- random convolution (off by default; `randconv_prob`): RandConv (Xu et al., "Robust and
  Generalizable Visual Representation Learning via Random Convolutions", ICLR 2021), the scene's
  textures and colours randomised rather than the camera's: the image, standardised per channel,
  goes through one 3 -> 3 convolution with a kernel size drawn from `randconv_kernels` (the
  paper's {1, 3, 5, 7} by default) and weights from
  N(0, 1 / (3 k^2)) (He's fan-in normal, as the paper draws them), and is mixed with itself as
  a x + (1 - a) conv(x), a ~ U(0, 1) (the paper's RandConv-mix). Local shape survives, local
  texture and colour do not, so a detector cannot lean on the renderer's materials. The result is
  given the input's per-channel mean and SD again (the paper feeds the standardised output to its
  network; ours reads 8-bit images). It runs first, on the scene, before the camera ops.
  `randconv_keep_below` (KITTI pixels; 0, off, by default): boxes lower than it keep their own
  pixels (widened by a quarter each side, edges feathered), and so do two same-sized decoy patches
  a box at random places, so an unconvolved patch does not mark a small object. Every RandConv run
  lost the generator's 25-40 px Cars (`results/detector.md`): a random 5 or 7 px
  kernel scrambles an object a few dozen pixels tall, where a near car keeps its shape.
  The paper's full method also trains on pairs: `Augmenter.pair` gives one sample without and with
  a random convolution, every other draw shared, for the consistency term that
  `TrainConfig.randconv_consistency` weighs (detector/loss.py).

`AugmentConfig.off()` switches the whole set off (evaluation-like inputs).

Every sample draws from its own generator seeded by (seed, epoch, index): the same settings
give the same batches whatever order or process builds them. The photometric parameters are
drawn in a fixed number of draws whatever is switched on (the noise and cut-out realisations
come from child seeds), so turning one op on or off does not change what the others draw.
"""
from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass, replace
from statistics import NormalDist

import cv2
import numpy as np

from detector.boxes import PAD_VALUE
from detector.data import DetectionData, Sample

MIXUP_MODES = ("none", "mixup", "thresholded")


@dataclass(frozen=True)
class AugmentConfig:
    mosaic: float = 1.0          # probability of a 4-image mosaic
    scale: float = 0.4           # zoom drawn from [1 - scale, 1 + scale]
    translate: float = 0.1       # shift drawn from +-translate x output size
    fliplr: float = 0.5
    hsv: tuple[float, float, float] = (0.015, 0.7, 0.4)  # hue, saturation, value gains
    mixup: str = "none"          # none | mixup | thresholded
    mixup_prob: float = 0.5      # 004 does not give one; half the samples are offered a partner
    mixup_alpha: float = 8.0     # Beta(alpha, alpha), 004
    mixup_iou: float = 0.4       # thresholded variant: mix only when every cross-image IoU is below this
    min_box: float = 2.0         # boxes thinner than this (pixels) after augmentation are dropped
    min_area_kept: float = 0.2   # ... and so are boxes cut to less than this share of their area
    # photometric set (module docstring: what each op mimics and why these ranges)
    photometric: bool = True     # master switch for everything below
    gain_prob: float = 0.5       # white balance: per-channel gain in [1 - gain, 1 + gain]
    gain: float = 0.1
    contrast_prob: float = 0.5   # contrast factor in [1 - contrast, 1 + contrast] about the mean luminance
    contrast: float = 0.25
    gamma_prob: float = 0.5      # gamma log-uniform in [1 / (1 + gamma), 1 + gamma]
    gamma: float = 0.3
    grey_prob: float = 0.05
    blur_prob: float = 0.3       # Gaussian blur, sigma in KITTI pixels (scaled to the working width)
    blur_sigma: tuple[float, float] = (0.3, 1.5)
    motion_prob: float = 0.1     # line kernel of this length (KITTI pixels) at a random angle
    motion_length: tuple[float, float] = (2.0, 6.0)
    noise_prob: float = 0.5      # Poisson-Gaussian sensor noise in linear intensity
    noise_full_well: tuple[float, float] = (3000.0, 20000.0)  # electrons at white, log-uniform
    noise_read: tuple[float, float] = (2.0, 8.0)              # read noise, electrons
    jpeg_prob: float = 0.2
    jpeg_quality: tuple[int, int] = (50, 95)
    cutout_prob: float = 0.25
    cutout_count: int = 3        # 1..cutout_count rectangles
    cutout_size: tuple[float, float] = (0.05, 0.3)  # rectangle height as a share of the image height
    cutout_max_cover: float = 0.5  # no labelled box more than this share covered (all rectangles together)
    randconv_prob: float = 0.0   # RandConv-mix texture randomisation (module docstring); off: recipes before it
    randconv_kernels: tuple[int, ...] = (1, 3, 5, 7)  # kernel sizes drawn uniformly (the paper's multi-scale set)
    randconv_keep_below: float = 0.0  # KITTI px: lower boxes keep their pixels (module docstring); 0: off

    def __post_init__(self):
        if self.mixup not in MIXUP_MODES:
            raise ValueError(f"unknown mixup mode {self.mixup!r}; choose one of {MIXUP_MODES}")
        for name in ("mosaic", "fliplr", "mixup_prob", "gain_prob", "contrast_prob", "gamma_prob", "grey_prob",
                     "blur_prob", "motion_prob", "noise_prob", "jpeg_prob", "cutout_prob", "cutout_max_cover",
                     "randconv_prob"):
            v = getattr(self, name)
            if not 0 <= v <= 1:
                raise ValueError(f"augmentation {name} must be a probability in [0, 1], got {v}")
        if not 0 <= self.scale < 1:
            raise ValueError(f"augmentation scale must be in [0, 1), got {self.scale}")
        for name in ("gain", "contrast"):
            if not 0 <= getattr(self, name) < 1:
                raise ValueError(f"augmentation {name} must be in [0, 1), got {getattr(self, name)}")
        if self.gamma < 0:
            raise ValueError(f"augmentation gamma must be >= 0, got {self.gamma}")
        for name, lo_min in (("blur_sigma", 0.0), ("motion_length", 0.0), ("noise_full_well", 1e-9),
                             ("noise_read", 0.0), ("jpeg_quality", 1), ("cutout_size", 1e-9)):
            lo, hi = getattr(self, name)
            if not lo_min <= lo <= hi:
                raise ValueError(f"augmentation {name} must be a range (low, high) with {lo_min} <= low <= high, "
                                 f"got {(lo, hi)}")
        if self.jpeg_quality[1] > 100 or self.cutout_size[1] > 1:
            raise ValueError("augmentation jpeg_quality must be within [1, 100] and cutout_size within (0, 1]")
        if self.cutout_count < 1:
            raise ValueError(f"augmentation cutout_count must be at least 1, got {self.cutout_count}")
        if self.randconv_keep_below < 0:
            raise ValueError(f"augmentation randconv_keep_below must be >= 0, got {self.randconv_keep_below}")
        if not self.randconv_kernels or any(int(k) != k or k < 1 or k % 2 == 0 for k in self.randconv_kernels):
            raise ValueError(f"augmentation randconv_kernels must be odd sizes >= 1, "
                             f"got {self.randconv_kernels}")

    @staticmethod
    def off() -> AugmentConfig:
        """Only the letterbox: evaluation-like inputs (no geometry, no colour, no photometric set)."""
        return AugmentConfig(mosaic=0.0, scale=0.0, translate=0.0, fliplr=0.0, hsv=(0.0, 0.0, 0.0),
                             photometric=False)

    def closing(self) -> AugmentConfig:
        """The close_mosaic phase: plain letterboxed images (no mosaic, zoom, shift or Mixup) with
        flips, HSV and the photometric set as configured. Photometric ops change no geometry and
        no box, so they do not bring back the train/test mismatch of mosaic and zoom that the phase
        removes; and the sim-to-real gap they bridge is photometric, so switching them off would fit
        the final (shipped) EMA weights to clean renderer statistics again (YOLOv5/8 likewise keep
        HSV on in their close-mosaic epochs)."""
        return replace(self, mosaic=0.0, scale=0.0, translate=0.0, mixup="none")


def pairwise_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,4) x (M,4) xyxy -> (N,M)."""
    lt = np.maximum(a[:, None, :2], b[None, :, :2])
    rb = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.clip(rb - lt, 0, None).prod(2)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    return inter / np.maximum(area_a[:, None] + area_b[None] - inter, 1e-12)


class Augmenter:
    """Builds training inputs of size (w, h) from a DetectionData."""

    def __init__(self, data: DetectionData, cfg: AugmentConfig, seed: int):
        self.data = data
        self.cfg = cfg
        self.seed = seed
        self.w, self.h = data.input_size

    def rng(self, epoch: int, index: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, epoch, index])

    def __call__(self, index: int, epoch: int, cfg: AugmentConfig | None = None) -> Sample:
        cfg = cfg or self.cfg
        rng = self.rng(epoch, index)
        s = self._scene(index, rng, cfg)
        if cfg.photometric:
            # one camera for the final image (after Mixup), so noise is not averaged down by the blend
            p = draw_photometric(cfg, rng, self.w / KITTI_WIDTH)
            s = Sample(apply_photometric(s.image, s.boxes, p, cfg), s.boxes, s.classes)
        return s

    def pair(self, index: int, epoch: int, cfg: AugmentConfig | None = None) -> tuple[Sample, Sample]:
        """RandConv's consistency pair: one sample seen without and with a random convolution, every
        other draw (geometry, flip, colour, camera, noise and cut-out realisations) shared. With
        randconv_prob 0 the first view is exactly what __call__ builds."""
        cfg = cfg or self.cfg
        if not cfg.photometric:
            raise ValueError("a RandConv pair needs the photometric set on (augmentation photometric)")
        rng = self.rng(epoch, index)
        s = self._scene(index, rng, cfg)
        p = draw_photometric(replace(cfg, randconv_prob=1.0), rng, self.w / KITTI_WIDTH)
        plain = replace(p, randconv=(0, 0.0))
        return tuple(Sample(apply_photometric(s.image, s.boxes, q, cfg), s.boxes, s.classes)
                     for q in (plain, p))

    def _scene(self, index: int, rng: np.random.Generator, cfg: AugmentConfig) -> Sample:
        """The sample before the photometric set: geometry, flip, colour jitter and Mixup."""
        s = self._one(index, rng, cfg)
        if cfg.mixup != "none" and rng.random() < cfg.mixup_prob:
            partner = self._one(int(rng.integers(len(self.data))), rng, cfg)
            s = mix(s, partner, cfg, rng)
        return s

    def _one(self, index: int, rng: np.random.Generator, cfg: AugmentConfig) -> Sample:
        if rng.random() < cfg.mosaic:
            canvas, boxes, classes = self._mosaic(index, rng)
        else:
            canvas, boxes, classes = self._letterboxed(index)
        img, boxes, classes = self._affine(canvas, boxes, classes, rng, cfg)
        if rng.random() < cfg.fliplr:
            img = img[:, ::-1].copy()
            boxes = boxes.copy()
            boxes[:, [0, 2]] = self.w - boxes[:, [2, 0]]
        if any(cfg.hsv):
            img = hsv_jitter(img, cfg.hsv, rng)
        return Sample(img, boxes, classes)

    def _letterboxed(self, index: int):
        s = self.data.samples[index]
        h, w = s.image.shape[:2]
        px, py = (self.w - w) // 2, (self.h - h) // 2
        canvas = np.full((self.h, self.w, 3), PAD_VALUE, np.uint8)
        canvas[py:py + h, px:px + w] = s.image
        return canvas, s.boxes + np.array([px, py, px, py]), s.classes

    def _mosaic(self, index: int, rng: np.random.Generator):
        """Four images meet at a random point of a 2w x 2h canvas, each in its own quadrant."""
        W, H = self.w, self.h
        canvas = np.full((2 * H, 2 * W, 3), PAD_VALUE, np.uint8)
        xc = int(rng.uniform(0.5 * W, 1.5 * W))
        yc = int(rng.uniform(0.5 * H, 1.5 * H))
        idx = [index] + [int(i) for i in rng.integers(len(self.data), size=3)]
        all_boxes, all_cls = [], []
        for q, i in enumerate(idx):
            s = self.data.samples[i]
            h, w = s.image.shape[:2]
            # canvas region (x1,y1,x2,y2) and the image's top-left corner on the canvas
            if q == 0:
                x1, y1, x2, y2 = max(xc - w, 0), max(yc - h, 0), xc, yc
                ox, oy = xc - w, yc - h
            elif q == 1:
                x1, y1, x2, y2 = xc, max(yc - h, 0), min(xc + w, 2 * W), yc
                ox, oy = xc, yc - h
            elif q == 2:
                x1, y1, x2, y2 = max(xc - w, 0), yc, xc, min(yc + h, 2 * H)
                ox, oy = xc - w, yc
            else:
                x1, y1, x2, y2 = xc, yc, min(xc + w, 2 * W), min(yc + h, 2 * H)
                ox, oy = xc, yc
            canvas[y1:y2, x1:x2] = s.image[y1 - oy:y2 - oy, x1 - ox:x2 - ox]
            b = s.boxes + np.array([ox, oy, ox, oy])
            b, keep = clip_boxes(b, (x1, y1, x2, y2), 0.0, 0.0)
            all_boxes.append(b)
            all_cls.append(s.classes[keep])
        return canvas, np.concatenate(all_boxes), np.concatenate(all_cls)

    def _affine(self, canvas: np.ndarray, boxes: np.ndarray, classes: np.ndarray,
                rng: np.random.Generator, cfg: AugmentConfig):
        """Zoom about the canvas centre and shift, into a w x h output."""
        ch, cw = canvas.shape[:2]
        zoom = rng.uniform(1 - cfg.scale, 1 + cfg.scale)
        tx = rng.uniform(-cfg.translate, cfg.translate) * self.w
        ty = rng.uniform(-cfg.translate, cfg.translate) * self.h
        ox = self.w / 2 + tx - zoom * cw / 2
        oy = self.h / 2 + ty - zoom * ch / 2
        if zoom == 1.0 and ox == 0 and oy == 0 and (cw, ch) == (self.w, self.h):
            img = canvas.copy()
        else:
            m = np.array([[zoom, 0, ox], [0, zoom, oy]], dtype=np.float64)
            img = cv2.warpAffine(canvas, m, (self.w, self.h), flags=cv2.INTER_LINEAR,
                                 borderValue=(PAD_VALUE,) * 3)
        b = boxes * zoom + np.array([ox, oy, ox, oy])
        b, keep = clip_boxes(b, (0, 0, self.w, self.h), cfg.min_box, cfg.min_area_kept)
        return img, b, classes[keep]


def clip_boxes(boxes: np.ndarray, region: tuple[float, float, float, float], min_size: float,
               min_area_kept: float) -> tuple[np.ndarray, np.ndarray]:
    """Clip xyxy boxes to a region; keep those at least min_size wide and high that kept at least
    min_area_kept of their area. Returns (kept clipped boxes, boolean mask)."""
    x1, y1, x2, y2 = region
    b = boxes.astype(np.float64).reshape(-1, 4)
    c = np.stack((b[:, 0].clip(x1, x2), b[:, 1].clip(y1, y2), b[:, 2].clip(x1, x2), b[:, 3].clip(y1, y2)), 1)
    w, h = c[:, 2] - c[:, 0], c[:, 3] - c[:, 1]
    area0 = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    keep = (w > min_size) & (h > min_size) & (w * h > min_area_kept * np.maximum(area0, 1e-12))
    keep &= (w > 0) & (h > 0)
    return c[keep], keep


def hsv_jitter(img: np.ndarray, gains: tuple[float, float, float], rng: np.random.Generator) -> np.ndarray:
    """Random hue shift and saturation/value scaling through lookup tables (RGB uint8 in and out)."""
    r = rng.uniform(-1, 1, 3) * np.asarray(gains) + 1
    hue, sat, val = cv2.split(cv2.cvtColor(img, cv2.COLOR_RGB2HSV))
    x = np.arange(256, dtype=np.float64)
    lut_h = ((x * r[0]) % 180).astype(np.uint8)
    lut_s = np.clip(x * r[1], 0, 255).astype(np.uint8)
    lut_v = np.clip(x * r[2], 0, 255).astype(np.uint8)
    hsv = cv2.merge((cv2.LUT(hue, lut_h), cv2.LUT(sat, lut_s), cv2.LUT(val, lut_v)))
    return cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)


def mix(a: Sample, b: Sample, cfg: AugmentConfig, rng: np.random.Generator) -> Sample:
    """Mixup (004): pixels blended with lambda ~ Beta(alpha, alpha), the boxes of both kept.
    The thresholded variant returns `a` unchanged when any box pair overlaps at IoU >= mixup_iou."""
    if cfg.mixup == "thresholded" and len(a.boxes) and len(b.boxes):
        if pairwise_iou(a.boxes, b.boxes).max() >= cfg.mixup_iou:
            return a
    lam = rng.beta(cfg.mixup_alpha, cfg.mixup_alpha)
    img = (a.image.astype(np.float32) * lam + b.image.astype(np.float32) * (1 - lam)).round().astype(np.uint8)
    return Sample(img, np.concatenate((a.boxes, b.boxes)), np.concatenate((a.classes, b.classes)))


# ---------------------------------------------------------------------------------------------
# Photometric set (sim-to-real); see the module docstring for the ranges and why.

KITTI_WIDTH = 1242            # px: blur sigma and motion length in AugmentConfig are KITTI pixels
LUMA = np.array([0.299, 0.587, 0.114])  # Rec. 601, as cv2's RGB2GRAY
ENCODE_LEVELS = 4096          # linear intensity is quantised this finely before the sRGB encode LUT


@dataclass(frozen=True)
class Photometric:
    """One sample's photometric draw; identity values where an op was not drawn."""
    gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
    contrast: float = 1.0
    gamma: float = 1.0
    grey: bool = False
    blur_sigma: float = 0.0                   # working pixels; 0: no Gaussian blur
    motion: tuple[float, float] = (0.0, 0.0)  # length (working pixels), angle (radians); length 0: none
    noise: tuple[float, float] = (0.0, 0.0)   # full well, read noise (electrons); full well 0: none
    jpeg_quality: int = 0                     # 0: no re-encode
    cutout: int = 0                           # number of rectangles to place
    randconv: tuple[int, float] = (0, 0.0)    # kernel size, weight of the input in the mix; size 0: none
    randconv_keep_below: float = 0.0          # working pixels: boxes lower than this keep their pixels
    seed: int = 0                             # of the noise, cut-out and random-kernel realisations


def draw_photometric(cfg: AugmentConfig, rng: np.random.Generator, px_scale: float = 1.0) -> Photometric:
    """Draws one sample's photometric parameters: always 22 uniforms from rng, whatever is on
    (the random convolution draws from a child of the sample's seed, so switching it on changes no
    other draw). px_scale converts KITTI pixels to working pixels (working width / KITTI_WIDTH)."""
    u = rng.random(22)
    on = u[:9] < np.array([cfg.gain_prob, cfg.contrast_prob, cfg.gamma_prob, cfg.grey_prob, cfg.blur_prob,
                           cfg.motion_prob, cfg.noise_prob, cfg.jpeg_prob, cfg.cutout_prob])

    def between(x: float, lo: float, hi: float) -> float:
        return lo + x * (hi - lo)

    gain = tuple(float(between(x, 1 - cfg.gain, 1 + cfg.gain)) for x in u[9:12])
    contrast = between(u[12], 1 - cfg.contrast, 1 + cfg.contrast)
    gamma = math.exp(between(u[13], -1, 1) * math.log1p(cfg.gamma))
    sigma = between(u[14], *cfg.blur_sigma) * px_scale
    length = between(u[15], *cfg.motion_length) * px_scale
    angle = u[16] * math.pi
    lo, hi = cfg.noise_full_well
    full_well = math.exp(between(u[17], math.log(lo), math.log(hi)))
    read = between(u[18], *cfg.noise_read)
    lo, hi = cfg.jpeg_quality
    quality = min(lo + int(u[19] * (hi - lo + 1)), hi)
    count = min(1 + int(u[20] * cfg.cutout_count), cfg.cutout_count)
    seed = int(u[21] * 2 ** 53)
    r = np.random.default_rng([seed, 2]).random(3)
    ks = cfg.randconv_kernels
    randconv = (int(ks[int(r[1] * len(ks))]), float(r[2]))
    return Photometric(gain=gain if on[0] else (1.0, 1.0, 1.0), contrast=contrast if on[1] else 1.0,
                       gamma=gamma if on[2] else 1.0, grey=bool(on[3]), blur_sigma=sigma if on[4] else 0.0,
                       motion=(length, angle) if on[5] else (0.0, 0.0),
                       noise=(full_well, read) if on[6] else (0.0, 0.0), jpeg_quality=quality if on[7] else 0,
                       cutout=count if on[8] else 0,
                       randconv=randconv if r[0] < cfg.randconv_prob else (0, 0.0),
                       randconv_keep_below=cfg.randconv_keep_below * px_scale, seed=seed)


def apply_photometric(img: np.ndarray, boxes: np.ndarray, p: Photometric, cfg: AugmentConfig) -> np.ndarray:
    """Applies a draw in camera order (random convolution of the scene, cut-out, blur, noise, tone,
    greyscale, JPEG); RGB uint8 in and out, the input untouched; boxes only limit the cut-out (they
    are not changed)."""
    if p.randconv[0]:
        conv = random_convolution(img, p.randconv[0], p.randconv[1], np.random.default_rng([p.seed, 3]))
        if p.randconv_keep_below > 0:
            keep = kept_regions(img.shape[:2], boxes, p.randconv_keep_below,
                                np.random.default_rng([p.seed, 4]))
            conv = np.rint(keep[..., None] * img + (1 - keep[..., None]) * conv).astype(np.uint8)
        img = conv
    if p.cutout:
        img = cutout(img, boxes, p.cutout, cfg.cutout_size, cfg.cutout_max_cover,
                     np.random.default_rng([p.seed, 0]))
    if p.blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), p.blur_sigma, borderType=cv2.BORDER_REFLECT_101)
    if p.motion[0] > 0:
        img = cv2.filter2D(img, -1, motion_kernel(*p.motion), borderType=cv2.BORDER_REFLECT_101)
    if p.noise[0] > 0:
        img = sensor_noise(img, p.noise[0], p.noise[1], np.random.default_rng([p.seed, 1]))
    if p.gain != (1.0, 1.0, 1.0) or p.contrast != 1.0 or p.gamma != 1.0:
        img = tone(img, p.gain, p.contrast, p.gamma)
    if p.grey:
        img = cv2.cvtColor(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)
    if p.jpeg_quality:
        img = jpeg(img, p.jpeg_quality)
    return img


def random_convolution(img: np.ndarray, k: int, keep: float, rng: np.random.Generator) -> np.ndarray:
    """RandConv-mix (module docstring): keep * x + (1 - keep) * (W * x) on the per-channel
    standardised image x, W a random 3 -> 3 k x k kernel, then the input's per-channel mean and SD
    given back; RGB uint8 in and out."""
    x = img.astype(np.float32)
    mean, sd = x.mean(axis=(0, 1)), x.std(axis=(0, 1)) + 1e-3
    x = (x - mean) / sd
    w = rng.normal(0.0, 1.0 / math.sqrt(3 * k * k), size=(3, 3, k, k)).astype(np.float32)
    out = np.empty_like(x)
    for o in range(3):
        out[..., o] = sum(cv2.filter2D(x[..., i], -1, w[o, i], borderType=cv2.BORDER_REFLECT_101)
                          for i in range(3))
    y = keep * x + (1 - keep) * out
    y = (y - y.mean(axis=(0, 1))) / (y.std(axis=(0, 1)) + 1e-6) * sd + mean
    return np.clip(np.rint(y), 0, 255).astype(np.uint8)


def kept_regions(shape: tuple[int, int], boxes: np.ndarray, below: float, rng: np.random.Generator,
                 decoys: int = 2) -> np.ndarray:
    """Weights in [0, 1] (H, W) of the input against its random convolution: 1 on each box lower
    than `below` and on `decoys` rectangles of its size at random places, so an unconvolved patch
    does not tell where a small object is; round each, a quarter of its size more fading out over
    about 2 px (so the box's outline against the scene stays the renderer's too)."""
    h, w = shape
    core, wide = np.zeros((h, w), np.float32), np.zeros((h, w), np.float32)
    for x1, y1, x2, y2 in boxes[(boxes[:, 3] - boxes[:, 1]) < below]:
        bw, bh = x2 - x1, y2 - y1
        centres = [((x1 + x2) / 2, (y1 + y2) / 2)]
        centres += [(rng.uniform(0, w), rng.uniform(0, h)) for _ in range(decoys)]
        for (u, v), (mask, grow) in itertools.product(centres, ((core, 1.0), (wide, 1.5))):
            a, b = int(max(round(u - grow * bw / 2), 0)), int(min(round(u + grow * bw / 2), w))
            c, d = int(max(round(v - grow * bh / 2), 0)), int(min(round(v + grow * bh / 2), h))
            mask[c:d, a:b] = 1.0
    if not core.any():
        return core
    faded = cv2.GaussianBlur(wide, (0, 0), 2.0, borderType=cv2.BORDER_REFLECT_101)
    return np.maximum(core, np.clip(faded, 0, 1))


def tone(img: np.ndarray, gain, contrast: float, gamma: float) -> np.ndarray:
    """Per-channel gain (white balance), then contrast about the mean luminance, then gamma
    (out = 255 (x / 255) ** gamma), all folded into one lookup table per channel."""
    g = np.asarray(gain, dtype=np.float64)
    mu = float(LUMA @ (g * np.asarray(cv2.mean(img)[:3])))
    y = mu + contrast * (np.arange(256.0)[:, None] * g - mu)
    y = 255 * (np.clip(y, 0, 255) / 255) ** gamma
    return cv2.LUT(img, np.round(y).astype(np.uint8).reshape(256, 1, 3))


def motion_kernel(length: float, angle: float) -> np.ndarray:
    """Normalised line kernel of the given length (pixels) and angle: the mid-points of 4 pieces a
    pixel, bilinearly splatted (variance along the line about length^2 / 12 + 1/6)."""
    r = length / 2
    k = 2 * math.ceil(r) + 3
    c = k // 2
    n = max(math.ceil(4 * length), 1)
    t = (np.arange(n) + 0.5) * (length / n) - r
    x, y = c + t * math.cos(angle), c + t * math.sin(angle)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    ker = np.zeros((k, k), np.float64)
    for dy, dx, wgt in ((0, 0, (1 - fx) * (1 - fy)), (0, 1, fx * (1 - fy)), (1, 0, (1 - fx) * fy), (1, 1, fx * fy)):
        np.add.at(ker, (y0 + dy, x0 + dx), wgt)
    return (ker / ker.sum()).astype(np.float32)


@functools.cache
def srgb_tables() -> tuple[np.ndarray, np.ndarray]:
    """(decode: 256 float32 linear intensities of the 8-bit sRGB codes, encode: ENCODE_LEVELS
    uint8 codes of linear k / (ENCODE_LEVELS - 1)); encode(round(decode(v) * 4095)) == v."""
    v = np.arange(256) / 255
    dec = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    lin = np.arange(ENCODE_LEVELS) / (ENCODE_LEVELS - 1)
    enc = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    return dec.astype(np.float32), np.round(enc * 255).astype(np.uint8)


@functools.cache
def _normal_table() -> np.ndarray:
    """Standard normal quantiles at the 256 mid-points of an 8-bit uniform, scaled so that the sum
    of two independent lookups has exactly unit variance (the mean is 0 by symmetry): a normal
    deviate from two raw random bytes (tails cut at 4.1 sigma), several times cheaper than
    Generator.standard_normal at this size."""
    nd = NormalDist()
    q = np.array([nd.inv_cdf((k + 0.5) / 256) for k in range(256)])
    return (q / np.sqrt(2 * np.mean(q ** 2))).astype(np.float32)


def standard_normal(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    """float32 (approximately) standard normal deviates of a 2D shape; see _normal_table."""
    h, w = shape
    raw = rng.bit_generator.random_raw(-(-2 * h * w // 8)).view(np.uint8)[:2 * h * w].reshape(2 * h, w)
    n = cv2.LUT(raw, _normal_table())
    n[:h] += n[h:]
    return n[:h]


def sensor_noise(img: np.ndarray, full_well: float, read: float, rng: np.random.Generator) -> np.ndarray:
    """Poisson-Gaussian noise in linear intensity: decode sRGB to L in [0, 1], add a zero-mean
    Gaussian of variance L / full_well + (read / full_well) ** 2 (shot noise of L * full_well
    electrons, in its usual Gaussian approximation, plus read noise), clip and encode again.
    L and its noise level come from lookup tables of the 8-bit codes, in encode-table units.
    Works in strips of rows so that no float temporary is large: fresh multi-megabyte numpy
    arrays (huge pages) cost more than the arithmetic here."""
    dec, enc = srgb_tables()
    top = ENCODE_LEVELS - 1
    std = (top * np.sqrt(dec.astype(np.float64) / full_well + (read / full_well) ** 2)).astype(np.float32)
    dec = dec * np.float32(top) + np.float32(0.5)  # +0.5: the truncation below rounds
    flat = img.reshape(img.shape[0], -1)
    out = np.empty_like(flat)
    rows = max(1, (1 << 17) // flat.shape[1])
    for y in range(0, flat.shape[0], rows):
        strip = flat[y:y + rows]
        lin = cv2.LUT(strip, dec)
        noise = cv2.LUT(strip, std)
        noise *= standard_normal(rng, strip.shape)
        lin += noise
        np.clip(lin, 0, top + 0.999, out=lin)
        out[y:y + rows] = np.take(enc, lin.astype(np.uint16))
    return out.reshape(img.shape)


def jpeg(img: np.ndarray, quality: int) -> np.ndarray:
    """Re-encode as JPEG at this quality (OpenCV's BGR order, so chroma is subsampled as usual)."""
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def cutout(img: np.ndarray, boxes: np.ndarray, count: int, size: tuple[float, float], max_cover: float,
           rng: np.random.Generator, tries: int = 10) -> np.ndarray:
    """Random erasing: up to `count` rectangles (height a `size` share of the image height, aspect
    1:3..3:1), each one grey level or uniform noise. A rectangle is kept only if afterwards no box
    has more than max_cover of its area under rectangles (the sum of their overlaps, which bounds
    the covered share from above); otherwise it is redrawn, at most `tries` times."""
    h, w = img.shape[:2]
    out = img.copy()
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    area = np.maximum((b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1]), 1e-12)
    cover = np.zeros(len(b))
    for _ in range(count):
        for _attempt in range(tries):
            u = rng.random(5)
            rh = (size[0] + u[0] * (size[1] - size[0])) * h
            rw = rh * math.exp((2 * u[1] - 1) * math.log(3))
            rh, rw = int(min(max(round(rh), 1), h)), int(min(max(round(rw), 1), w))
            x0, y0 = int(u[2] * (w - rw + 1)), int(u[3] * (h - rh + 1))
            ix = np.clip(np.minimum(b[:, 2], x0 + rw) - np.maximum(b[:, 0], x0), 0, None)
            iy = np.clip(np.minimum(b[:, 3], y0 + rh) - np.maximum(b[:, 1], y0), 0, None)
            new = cover + ix * iy / area
            if (new <= max_cover + 1e-9).all():
                break
        else:
            continue
        cover = new
        if u[4] < 0.5:
            out[y0:y0 + rh, x0:x0 + rw] = int(rng.integers(256))
        else:
            out[y0:y0 + rh, x0:x0 + rw] = rng.integers(0, 256, (rh, rw, 3), dtype=np.uint8)
    return out
