"""Photometric (sim-to-real) augmentation: each op does what it says with the drawn strength,
boxes are never changed, cut-out respects its cover limit, samples are seeded, off() is off."""
from dataclasses import replace

import numpy as np
import pytest
import torch
from click.testing import CliRunner

from detector.augment import (
    AugmentConfig,
    Augmenter,
    Photometric,
    apply_photometric,
    cutout,
    draw_photometric,
    jpeg,
    kept_regions,
    motion_kernel,
    random_convolution,
    sensor_noise,
    srgb_tables,
    standard_normal,
    tone,
)
from detector.data import DetectionData
from tests.detector.toydata import write_toy_dataset

ALL_OFF = {k: 0.0 for k in ("gain_prob", "contrast_prob", "gamma_prob", "grey_prob", "blur_prob", "motion_prob",
                            "noise_prob", "jpeg_prob", "cutout_prob")}
ALL_ON = {k: 1.0 for k in ALL_OFF}


def only(**kw) -> AugmentConfig:
    """Photometric set on with every op off except the given ones."""
    return AugmentConfig(**{**ALL_OFF, **kw})


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    root = write_toy_dataset(tmp_path_factory.mktemp("toy") / "ds", 6, seed=11, size=(256, 96))
    return DetectionData(str(root), "train", (256, 96), progress=False)


def test_off_switches_the_set_off_and_closing_keeps_it():
    assert AugmentConfig().photometric and not AugmentConfig.off().photometric
    c = AugmentConfig(mixup="mixup", gain=0.2, noise_prob=0.7).closing()
    assert (c.mosaic, c.scale, c.translate, c.mixup) == (0.0, 0.0, 0.0, "none")
    assert c.photometric and c.gain == 0.2 and c.noise_prob == 0.7 and c.hsv == AugmentConfig().hsv


def test_off_and_zero_probabilities_leave_the_image_untouched(toy):
    s = Augmenter(toy, AugmentConfig.off(), seed=0)(1, 0)
    assert np.array_equal(s.image, toy.samples[1].image)
    geo_off = replace(AugmentConfig.off(), photometric=True, **ALL_OFF)
    s = Augmenter(toy, geo_off, seed=0)(1, 0)
    assert np.array_equal(s.image, toy.samples[1].image)
    img = toy.samples[1].image.copy()
    p = draw_photometric(only(), np.random.default_rng(0))
    assert p == replace(Photometric(), seed=p.seed)
    assert np.array_equal(apply_photometric(img, toy.samples[1].boxes, p, only()), toy.samples[1].image)


@pytest.mark.parametrize("epoch", range(3))
def test_photometric_ops_keep_boxes_and_change_pixels(toy, epoch):
    on = AugmentConfig(mixup="mixup", **ALL_ON)
    a, b = Augmenter(toy, on, seed=7), Augmenter(toy, replace(on, photometric=False), seed=7)
    for i in range(len(toy)):
        src = toy.samples[i].image.copy()
        s1, s2 = a(i, epoch), b(i, epoch)
        assert np.array_equal(s1.boxes, s2.boxes) and np.array_equal(s1.classes, s2.classes)
        assert s1.image.shape == s2.image.shape and s1.image.dtype == np.uint8
        assert not np.array_equal(s1.image, s2.image)
        assert np.array_equal(toy.samples[i].image, src)  # the cached frame is never written to


def test_same_seed_epoch_index_give_identical_bytes(toy):
    cfg = AugmentConfig(mixup="mixup", **ALL_ON)
    a, b = Augmenter(toy, cfg, seed=5), Augmenter(toy, cfg, seed=5)
    forward = [a(i, 2).image.tobytes() for i in range(len(toy))]
    backward = [b(i, 2).image.tobytes() for i in reversed(range(len(toy)))][::-1]
    assert forward == backward
    assert a(0, 2).image.tobytes() != a(0, 3).image.tobytes() != Augmenter(toy, cfg, seed=6)(0, 2).image.tobytes()


def test_one_op_switched_does_not_change_the_other_draws():
    p1 = draw_photometric(AugmentConfig(**ALL_ON), np.random.default_rng([1, 2, 3]))
    p2 = draw_photometric(AugmentConfig(**{**ALL_ON, "noise_prob": 0.0, "jpeg_prob": 0.0}),
                          np.random.default_rng([1, 2, 3]))
    assert p2.noise == (0.0, 0.0) and p2.jpeg_quality == 0 and p1.noise[0] > 0 and p1.jpeg_quality > 0
    assert replace(p1, noise=(0.0, 0.0), jpeg_quality=0) == p2


def test_draws_stay_in_their_ranges_and_blur_scales_with_width():
    cfg = AugmentConfig(**ALL_ON)
    ps = [draw_photometric(cfg, np.random.default_rng(i), px_scale=0.5) for i in range(300)]
    gains = np.array([p.gain for p in ps])
    assert (gains >= 0.9).all() and (gains <= 1.1).all() and gains.std() > 0.04
    assert all(0.75 <= p.contrast <= 1.25 and 1 / 1.3 <= p.gamma <= 1.3 for p in ps)
    sig = np.array([p.blur_sigma for p in ps])
    assert sig.min() >= 0.15 and sig.max() <= 0.75 and sig.max() > 0.7  # (0.3, 1.5) KITTI px at half width
    fw = np.array([p.noise[0] for p in ps])
    assert fw.min() >= 3000 and fw.max() <= 20000
    assert np.median(fw) == pytest.approx(np.sqrt(3000 * 20000), rel=0.2)  # log-uniform
    q = [p.jpeg_quality for p in ps]
    assert min(q) == 50 and max(q) == 95
    assert {p.cutout for p in ps} == {1, 2, 3}
    # probabilities: 300 draws at p = 0.3 -> 90 +- 8 (sd)
    n_blur = sum(draw_photometric(AugmentConfig(), np.random.default_rng(i)).blur_sigma > 0 for i in range(300))
    assert 60 <= n_blur <= 120


def test_gain_changes_channel_means_by_the_drawn_factor():
    img = np.random.default_rng(0).integers(40, 190, (120, 160, 3), dtype=np.uint8)
    cfg = only(gain_prob=1.0, gain=0.25)
    for seed in range(5):
        p = draw_photometric(cfg, np.random.default_rng(seed))
        assert max(abs(g - 1) for g in p.gain) > 0.02 and (p.contrast, p.gamma) == (1.0, 1.0)
        out = apply_photometric(img, np.zeros((0, 4)), p, cfg)
        mean_in = img.reshape(-1, 3).mean(0)
        # rounding to 8 bits moves each pixel by at most 0.5; gains are >= 2% (>= 2 DN) off 1 here
        np.testing.assert_allclose(out.reshape(-1, 3).mean(0), np.array(p.gain) * mean_in, atol=0.5)


def test_contrast_scales_about_the_mean_and_gamma_is_a_power():
    rng = np.random.default_rng(1)
    img = rng.integers(90, 166, (100, 100, 3), dtype=np.uint8)
    out = tone(img, (1.0, 1.0, 1.0), 0.8, 1.0).astype(float)
    assert out.mean() == pytest.approx(img.mean(), abs=0.1)
    assert out.std() == pytest.approx(0.8 * img.std(), rel=0.01)
    flat = np.full((4, 4, 3), 100, np.uint8)
    assert (tone(flat, (1.0, 1.0, 1.0), 1.0, 1.3) == round(255 * (100 / 255) ** 1.3)).all()


@pytest.mark.parametrize("level", [60, 128, 200])
def test_noise_has_the_poisson_gaussian_variance_in_linear_intensity(level):
    full_well, read = 800.0, 4.0
    n = 256 * 256 * 3
    img = np.full((256, 256, 3), level, np.uint8)
    out = sensor_noise(img, full_well, read, np.random.default_rng(level))
    dec, _ = srgb_tables()
    lin = dec[out].astype(np.float64)
    L = float(dec[level])
    step = float(dec[level + 1] - dec[level - 1]) / 2  # 8-bit code step in linear units: rounding adds step^2 / 12
    want = L / full_well + (read / full_well) ** 2 + step ** 2 / 12
    # sample variance of n values: relative sd sqrt(2 / n) = 0.32%; 5 sd plus 1% for the curve's bend
    assert lin.var() == pytest.approx(want, rel=5 * np.sqrt(2 / n) + 0.01)
    assert lin.mean() == pytest.approx(L, abs=5 * np.sqrt(want / n) + 0.002 * L)


def test_noise_is_signal_dependent_and_seeded():
    dark, bright = (sensor_noise(np.full((64, 64, 3), v, np.uint8), 2000.0, 0.0, np.random.default_rng(0))
                    for v in (50, 220))
    dec, _ = srgb_tables()
    ratio = dec[bright].astype(float).var() / dec[dark].astype(float).var()
    assert ratio == pytest.approx(dec[220] / dec[50], rel=0.15)  # shot noise: variance proportional to L
    img = np.random.default_rng(3).integers(0, 256, (50, 70, 3), dtype=np.uint8)
    a = sensor_noise(img, 5000.0, 5.0, np.random.default_rng(9))
    assert np.array_equal(a, sensor_noise(img, 5000.0, 5.0, np.random.default_rng(9)))
    assert not np.array_equal(a, sensor_noise(img, 5000.0, 5.0, np.random.default_rng(10)))


def test_standard_normal_moments():
    x = standard_normal(np.random.default_rng(0), (500, 400)).astype(np.float64)
    sd = 1 / np.sqrt(x.size)
    assert abs(x.mean()) < 5 * sd and x.var() == pytest.approx(1.0, abs=5 * np.sqrt(2) * sd)
    assert (np.abs(x) > 2).mean() == pytest.approx(0.0455, abs=0.003)


def test_gaussian_and_motion_blur():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (80, 120, 3), dtype=np.uint8)
    cfg = only(blur_prob=1.0)
    p = replace(Photometric(), blur_sigma=1.2)
    out = apply_photometric(img, np.zeros((0, 4)), p, cfg).astype(float)
    # white noise through a Gaussian of sigma s keeps 1 / (4 pi s^2) of its variance
    assert out.var() == pytest.approx(img.var() / (4 * np.pi * 1.2 ** 2), rel=0.15)
    assert out.mean() == pytest.approx(img.mean(), abs=0.5)
    k = motion_kernel(6.0, 0.0)
    assert k.sum() == pytest.approx(1.0) and k.shape[0] % 2 == 1
    c = k.shape[0] // 2
    ys, xs = np.mgrid[:k.shape[0], :k.shape[1]] - c
    assert (k * xs).sum() == pytest.approx(0, abs=1e-6) and (k * ys ** 2).sum() == pytest.approx(0, abs=1e-6)
    # a 6 px line: variance L^2 / 12, plus about 1/6 from the bilinear splat
    assert (k * xs ** 2).sum() == pytest.approx(6.0 ** 2 / 12 + 1 / 6, rel=0.03)
    kd = motion_kernel(4.0, np.pi / 2)
    ys, xs = np.mgrid[:kd.shape[0], :kd.shape[1]] - kd.shape[0] // 2
    assert (kd * xs ** 2).sum() < 1e-6 and (kd * ys ** 2).sum() == pytest.approx(4.0 ** 2 / 12 + 1 / 6, rel=0.03)


def test_greyscale_and_jpeg_keep_channel_order():
    img = np.zeros((64, 64, 3), np.uint8)
    img[..., 0] = 200  # red
    img[16:48, 16:48] = (30, 180, 60)  # a green square
    out = jpeg(img, 60)
    assert out.shape == img.shape and not np.array_equal(out, img)
    assert np.abs(out.astype(int) - img).mean() < 4
    assert out[2, 2, 0] > 150 and out[2, 2, 2] < 40 and out[32, 32, 1] > 150
    g = apply_photometric(img, np.zeros((0, 4)), replace(Photometric(), grey=True), only())
    assert (g[..., 0] == g[..., 1]).all() and (g[..., 1] == g[..., 2]).all()
    assert g[2, 2, 0] == round(0.299 * 200)


def _box_image():
    img = np.zeros((120, 200, 3), np.uint8)
    boxes = np.array([[10, 10, 40, 50], [60, 20, 190, 110], [150, 5, 170, 15], [5, 80, 55, 115]], float)
    for x1, y1, x2, y2 in boxes.astype(int):
        img[y1:y2, x1:x2] = (255, 0, 255)  # magenta: no grey fill can equal it
    return img, boxes


@pytest.mark.parametrize("max_cover", [0.3, 0.5])
def test_cutout_never_covers_more_than_the_allowed_share_of_a_box(max_cover):
    img, boxes = _box_image()
    worst, touched = 0.0, 0
    for seed in range(150):
        out = cutout(img, boxes, 6, (0.1, 0.8), max_cover, np.random.default_rng(seed))
        assert np.array_equal(img, _box_image()[0])  # input untouched
        for x1, y1, x2, y2 in boxes.astype(int):
            changed = (out[y1:y2, x1:x2] != img[y1:y2, x1:x2]).any(-1).mean()
            assert changed <= max_cover + 1e-9, (seed, changed)
            worst = max(worst, changed)
            touched += changed > 0
    assert worst > 0.8 * max_cover and touched > 100  # the limit is reached, not trivially kept


def test_cutout_without_a_limit_would_erase_boxes():
    """Control for the test above: the same rectangles, unconstrained, do cover boxes beyond it."""
    img, boxes = _box_image()
    worst = 0.0
    for seed in range(50):
        out = cutout(img, boxes, 6, (0.1, 0.8), 1.0, np.random.default_rng(seed))
        for x1, y1, x2, y2 in boxes.astype(int):
            worst = max(worst, (out[y1:y2, x1:x2] != img[y1:y2, x1:x2]).any(-1).mean())
    assert worst > 0.9


def test_cutout_through_the_augmenter_keeps_every_box(toy):
    cfg = replace(AugmentConfig.off(), photometric=True, **{**ALL_OFF, "cutout_prob": 1.0, "cutout_count": 5,
                                                           "cutout_size": (0.2, 0.6), "cutout_max_cover": 0.4})
    aug = Augmenter(toy, cfg, seed=1)
    n_changed = 0
    for epoch in range(5):
        for i in range(len(toy)):
            s, src = aug(i, epoch), toy.samples[i]
            assert np.array_equal(s.boxes, src.boxes) and np.array_equal(s.classes, src.classes)
            for x1, y1, x2, y2 in s.boxes:
                a, b = s.image[int(np.ceil(y1)):int(y2), int(np.ceil(x1)):int(x2)], \
                    src.image[int(np.ceil(y1)):int(y2), int(np.ceil(x1)):int(x2)]
                assert (a != b).any(-1).mean() <= 0.4 + 1e-9
            n_changed += not np.array_equal(s.image, src.image)
    assert n_changed >= 25


def test_random_convolution_switched_on_changes_no_other_draw():
    for i in range(20):
        off = draw_photometric(AugmentConfig(**ALL_ON), np.random.default_rng([4, i]))
        on = draw_photometric(AugmentConfig(**ALL_ON, randconv_prob=1.0), np.random.default_rng([4, i]))
        assert off.randconv == (0, 0.0) and on.randconv[0] in (1, 3, 5, 7) and 0 <= on.randconv[1] < 1
        assert replace(on, randconv=(0, 0.0)) == off
    ks = [draw_photometric(AugmentConfig(randconv_prob=1.0), np.random.default_rng(i)).randconv[0] for i in range(200)]
    assert set(ks) == {1, 3, 5, 7}
    n = sum(draw_photometric(AugmentConfig(randconv_prob=0.5), np.random.default_rng(i)).randconv[0] > 0
            for i in range(300))
    assert 125 <= n <= 175  # 300 draws at p = 0.5: 150 +- 9 (sd)
    small = [draw_photometric(AugmentConfig(randconv_prob=1.0, randconv_kernels=(1, 3)), np.random.default_rng(i))
             for i in range(200)]
    assert {p.randconv[0] for p in small} == {1, 3}
    # a kernel set changes only which size is drawn, not the mix weight nor any other draw
    same = draw_photometric(AugmentConfig(randconv_prob=1.0), np.random.default_rng(7))
    assert replace(small[7], randconv=(0, 0.0)) == replace(same, randconv=(0, 0.0))
    assert small[7].randconv[1] == same.randconv[1]


def test_random_convolution_of_size_one_is_an_affine_colour_map_with_the_input_statistics():
    img = np.clip(np.random.default_rng(3).normal([120, 110, 100], [20, 15, 25], (64, 96, 3)), 0, 255)
    img = img.astype(np.uint8)
    out = random_convolution(img, 1, 0.3, np.random.default_rng(5))
    assert out.shape == img.shape and out.dtype == np.uint8 and not np.array_equal(out, img)
    x = np.c_[img.reshape(-1, 3).astype(np.float64), np.ones(img.shape[0] * img.shape[1])]
    y = out.reshape(-1, 3).astype(np.float64)
    inside = ((y > 0) & (y < 255)).all(axis=1)
    coef, *_ = np.linalg.lstsq(x[inside], y[inside], rcond=None)
    assert np.abs(x[inside] @ coef - y[inside]).max() < 0.55  # affine per pixel, up to rounding (0.5)
    # each channel given the input's mean and SD back (rounding moves them a little)
    assert inside.mean() > 0.999
    assert np.allclose(y.mean(0), img.reshape(-1, 3).mean(0), atol=0.05)
    assert np.allclose(y.std(0), img.reshape(-1, 3).std(0), rtol=0.01)


def test_random_convolution_mixes_neighbours_and_is_seeded():
    img = np.zeros((32, 32, 3), np.uint8)
    img[16, 16] = 255  # one bright pixel on black: the kernel's footprint shows around it
    rng = np.random.default_rng
    for k in (3, 7):
        out = random_convolution(img, k, 0.0, rng(9)).astype(int)
        changed = np.argwhere((out != np.median(out, axis=(0, 1))).any(axis=2))
        assert changed.min(0).tolist() == [16 - k // 2] * 2 and changed.max(0).tolist() == [16 + k // 2] * 2
    assert np.array_equal(random_convolution(img, 5, 0.4, rng(1)), random_convolution(img, 5, 0.4, rng(1)))
    assert not np.array_equal(random_convolution(img, 5, 0.4, rng(1)), random_convolution(img, 5, 0.4, rng(2)))


def test_randconv_pair_is_the_plain_sample_and_its_convolved_twin(toy):
    cfg = AugmentConfig(**ALL_ON, randconv_kernels=(1,), mosaic=0.5)
    aug = Augmenter(toy, cfg, seed=4)
    differ = 0
    for i in range(len(toy)):
        plain, conv = aug.pair(i, 2)
        ref = aug(i, 2)  # randconv_prob 0: the first view is what plain training draws
        assert plain.image.tobytes() == ref.image.tobytes()
        assert np.array_equal(plain.boxes, ref.boxes) and np.array_equal(conv.boxes, ref.boxes)
        assert np.array_equal(plain.classes, conv.classes)
        differ += not np.array_equal(plain.image, conv.image)
        again = aug.pair(i, 2)
        assert again[0].image.tobytes() == plain.image.tobytes() and again[1].image.tobytes() == conv.image.tobytes()
    assert differ >= len(toy) - 1  # one draw here keeps 99.8 % of the input: greyscale rounds it away
    # with every camera op off, the twin is exactly the random convolution of the first view that the
    # sample's own draw names (kernel, mix weight, realisation): no other draw differs between them
    bare = Augmenter(toy, only(), seed=4)
    for i in range(len(toy)):
        plain, conv = bare.pair(i, 1)
        rng = bare.rng(1, i)
        bare._scene(i, rng, bare.cfg)  # the geometry and colour draws come first
        p = draw_photometric(AugmentConfig(**ALL_OFF, randconv_prob=1.0), rng, bare.w / 1242)
        assert p.randconv[0] in (1, 3, 5, 7)
        want = random_convolution(plain.image, *p.randconv, np.random.default_rng([p.seed, 3]))
        assert want.tobytes() == conv.image.tobytes()
    with pytest.raises(ValueError, match="photometric"):
        Augmenter(toy, replace(cfg, photometric=False), seed=4).pair(0, 0)


def test_bad_photometric_config_is_named():
    with pytest.raises(ValueError, match="blur_sigma"):
        AugmentConfig(blur_sigma=(2.0, 1.0))
    with pytest.raises(ValueError, match="noise_prob"):
        AugmentConfig(noise_prob=1.5)
    with pytest.raises(ValueError, match="jpeg_quality"):
        AugmentConfig(jpeg_quality=(50, 101))
    with pytest.raises(ValueError, match="cutout_max_cover"):
        AugmentConfig(cutout_max_cover=-0.1)
    with pytest.raises(ValueError, match="randconv_prob"):
        AugmentConfig(randconv_prob=2.0)
    for bad in ((), (2,), (1, 0)):
        with pytest.raises(ValueError, match="randconv_kernels"):
            AugmentConfig(randconv_kernels=bad)


def test_cli_wires_the_photometric_options_into_the_saved_config(tmp_path):
    from testbed.cli import cli
    root = write_toy_dataset(tmp_path / "ds", 4, seed=2, size=(128, 64))
    args = ["train-detector", "--data", str(root), "--out", str(tmp_path / "run"), "--epochs", "1",
            "--img-size", "128", "64", "--batch", "4", "--eval-every", "0", "--threads", "1",
            "--wb-gain", "0.2", "--blur-sigma", "0.5", "1.0", "--noise-prob", "0.9",
            "--noise-full-well", "1000", "5000", "--jpeg-prob", "0.0", "--cutout-prob", "0.4",
            "--randconv-prob", "0.3", "--randconv-kernel", "1", "--randconv-kernel", "3",
            "--randconv-keep-below", "40"]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    aug = torch.load(tmp_path / "run" / "weights.pt", weights_only=True)["train_config"]["augment"]
    assert aug["photometric"] is True and aug["gain"] == 0.2 and aug["blur_sigma"] == [0.5, 1.0]
    assert aug["noise_prob"] == 0.9 and aug["noise_full_well"] == [1000.0, 5000.0]
    assert aug["jpeg_prob"] == 0.0 and aug["cutout_prob"] == 0.4 and aug["randconv_prob"] == 0.3
    assert aug["randconv_kernels"] == [1, 3] and aug["randconv_keep_below"] == 40.0
    assert AugmentConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in aug.items()}).gain == 0.2
    res = CliRunner().invoke(cli, [*args[:4], str(tmp_path / "run2"), *args[5:], "--no-photometric"])
    assert res.exit_code == 0, res.output
    aug = torch.load(tmp_path / "run2" / "weights.pt", weights_only=True)["train_config"]["augment"]
    assert aug["photometric"] is False
    res = CliRunner().invoke(cli, [*args[:4], str(tmp_path / "run3"), *args[5:], "--blur-sigma", "2", "1"])
    assert res.exit_code != 0 and "blur_sigma" in res.output
    res = CliRunner().invoke(cli, [*args[:4], str(tmp_path / "run4"), *args[5:], "--randconv-kernel", "2"])
    assert res.exit_code != 0 and "randconv_kernels" in res.output
    # the consistency pairs draw their own RandConv view: with --randconv-prob too it is refused by name
    res = CliRunner().invoke(cli, [*args[:4], str(tmp_path / "run5"), *args[5:], "--randconv-consistency", "12"])
    assert res.exit_code != 0 and "randconv_prob" in res.output
    pairs = [a for a in args if a not in ("--randconv-prob", "0.3")]
    res = CliRunner().invoke(cli, [*pairs[:4], str(tmp_path / "run6"), *pairs[5:], "--randconv-consistency", "12"])
    assert res.exit_code == 0, res.output
    saved = torch.load(tmp_path / "run6" / "weights.pt", weights_only=True)["train_config"]
    assert saved["randconv_consistency"] == 12.0 and saved["augment"]["randconv_kernels"] == [1, 3]
    assert saved["randconv_consistency_target"] == "mutual"
    res = CliRunner().invoke(cli, [*pairs[:4], str(tmp_path / "run7"), *pairs[5:], "--randconv-consistency", "12",
                                   "--randconv-consistency-target", "plain"])
    assert res.exit_code == 0, res.output
    saved = torch.load(tmp_path / "run7" / "weights.pt", weights_only=True)["train_config"]
    assert saved["randconv_consistency_target"] == "plain"


def test_small_boxes_keep_their_pixels_under_a_random_convolution():
    """Below `randconv_keep_below` a box (and a quarter of its size round it) keeps the input's
    pixels exactly; a tall box, and the image far from any kept patch, are convolved; the same
    number of same-sized decoy patches keep theirs; with the option off the result is the plain
    random convolution's, byte for byte."""
    img = np.clip(np.random.default_rng(3).normal(120, 40, (200, 400, 3)), 0, 255).astype(np.uint8)
    boxes = np.array([[40.0, 60.0, 80.0, 80.0], [200.0, 20.0, 300.0, 180.0]])  # 20 px and 160 px tall
    p = Photometric(randconv=(5, 0.0), randconv_keep_below=30.0, seed=11)
    out = apply_photometric(img, boxes, p, AugmentConfig())
    conv = random_convolution(img, 5, 0.0, np.random.default_rng([11, 3]))
    assert np.array_equal(out[60:80, 40:80], img[60:80, 40:80])  # the small box itself, exactly
    assert (out[55:85, 30:90] != conv[55:85, 30:90]).any(axis=2).mean() > 0.9  # and round it, mostly
    keep = kept_regions(img.shape[:2], boxes, 30.0, np.random.default_rng([11, 4]))
    assert np.array_equal(out[keep == 0], conv[keep == 0])
    assert (keep[:, 200:301][20:181] < 1).mean() > 0.9  # the tall box is mostly convolved
    # 1 + 2 decoys: the kept area is about three times the widened box's (60 x 30 px), less overlaps
    assert 0.8 * 1800 < (keep > 0.5).sum() <= 3 * 1800 + 200
    plain = apply_photometric(img, boxes, replace(p, randconv_keep_below=0.0), AugmentConfig())
    assert np.array_equal(plain, conv)
    with pytest.raises(ValueError, match="randconv_keep_below"):
        AugmentConfig(randconv_keep_below=-1.0)
