"""The bootstrap behind each fidelity verdict: frames keep their values through chunks and
resampling, intervals computed by hand (frames drawn one by one or a drive at a time), and the real
dev frames against themselves."""

from __future__ import annotations

import numpy as np
import pytest

from fidelity import compare, compute_stats
from fidelity.bootstrap import Interval, intervals
from fidelity.catalog import STATS, Share, Stat, car_points, med, ring_median
from fidelity.stats import Acc, DatasetStats, Draws, merge


def _chunks() -> list[Acc]:
    a = Acc()
    a.frames.append("a")
    a.put("x", [1.0, 2.0])
    a.row("r", [1.0, 1.0])
    a.frames.append("b")
    a.put("x", 3.0)
    b = Acc()
    b.frames.append("c")
    b.put("x", [4.0, 5.0, 6.0])
    b.row("r", [2.0, 2.0])
    return [a, b]


def test_values_keep_their_frame_through_chunks_and_resampling():
    d = merge("root", None, {}, _chunks())
    assert d.value_frames["x"].tolist() == [0, 0, 1, 2, 2, 2] and d.row_frames["r"].tolist() == [0, 2]
    same = d.resample(np.arange(3))
    assert same.get("x").tolist() == d.get("x").tolist() and same.rows["r"].tolist() == d.rows["r"].tolist()
    draw = d.resample(np.array([2, 0, 0, 1]))
    assert draw.frames == ["c", "a", "a", "b"]
    assert draw.get("x").tolist() == [4.0, 5.0, 6.0, 1.0, 2.0, 1.0, 2.0, 3.0]
    assert draw.rows["r"].tolist() == [[2.0, 2.0], [1.0, 1.0], [1.0, 1.0]]
    assert draw.value_frames["x"].tolist() == [0, 0, 0, 1, 1, 2, 2, 3] and draw.row_frames["r"].tolist() == [0, 1, 2]
    assert draw.resample(np.array([3])).get("x").tolist() == [3.0]  # a draw draws again
    with pytest.raises(RuntimeError, match="before its frame"):
        Acc().put("x", 1.0)


def _one(values: list[float]) -> DatasetStats:
    n = len(values)
    return DatasetStats("x", None, [str(i) for i in range(n)], [], {"images": True},
                        {"images.grey_mean": np.array(values)}, {}, {},
                        {"images.grey_mean": np.arange(n)}, {})


def test_all_draws_at_once_give_each_draws_own_numbers():
    """Draws (every draw from frame counts, one sort) against resampling each draw and computing
    the statistic on it: the same numbers, with ties, NaN, empty frames and an empty draw."""
    rng = np.random.default_rng(5)
    acc = Acc()
    for f in range(7):
        acc.frames.append(str(f))
        n = int(rng.integers(0, 4))  # frames 0-6 hold 0-3 values, some tied, some NaN
        acc.put("x", np.round(rng.normal(size=n), 1) if f != 3 else [np.nan, 1.0])
        acc.row("r", np.where(rng.uniform(size=3) < 0.2, np.nan, rng.integers(0, 3, 3).astype(float)))
        acc.put("lidar.car_points", rng.integers(0, 50, 2).astype(float))
        acc.put("lidar.car_distance_m", rng.uniform(0, 80, 2))
        acc.put("lidar.car_occluded", rng.integers(0, 3, 2).astype(float))
    d = merge("root", None, {}, [acc])
    picks = [rng.integers(7, size=7) for _ in range(40)] + [np.array([0, 0, 0, 0, 0, 0, 0])]
    draws = Draws.of(d, picks)
    summaries = [med("x"), Share("x", lambda v: v > 0), ring_median("r", np.nanmax),
                 ring_median("r", lambda m: m[0]), car_points(0, 40), car_points(20, 80, visible=True)]
    for s in summaries:
        want = np.array([s(d.resample(p)) for p in picks])
        np.testing.assert_array_equal(s.draws(draws), want)
    assert {type(s.value) for s in STATS} <= {type(x) for x in summaries}


def test_an_interval_by_hand():
    """Real frames 1 and 3, one sim frame 2: a draw's real median is 1, 2 or 3 (a quarter, a half,
    a quarter of the draws), so the difference is +100 %, 0 or -33 %: the verdict (0, pass) is
    undecided at +-15 %. Real 1.0 and 1.1 against 2: every draw fails, +82 % to +100 %."""
    stat = (Stat("images.grey_mean", "grey", "", med("images.grey_mean")),)
    (wide,) = intervals(_one([2.0]), _one([1.0, 3.0]), stats=stat).values()
    assert wide == Interval(pytest.approx(-1 / 3), 1.0)
    assert not wide.decides("pass", 0.15) and wide.decides("pass", 1.0)
    (far,) = intervals(_one([2.0]), _one([1.0, 1.1]), stats=stat).values()
    assert far == Interval(pytest.approx(0.9 / 1.1), 1.0) and far.decides("fail", 0.15)
    assert not far.decides("fail", 0.9) and not far.decides("pass", 0.15)
    assert intervals(_one([2.0]), _one([1.0]), draws=0, stats=stat) == {"images.grey_mean": None}


def test_a_drive_is_drawn_whole():
    """Real: nine frames of one drive at 1.0 and two lone frames at 3.0, against a sim frame at 2.0.
    Drawn as eleven frames, a draw's median is 3.0 only when six or more of its eleven are lone
    frames (binomial, p = 2/11: 0.7 % of the draws), so the central 95 % is +100 % alone: a decided
    fail. Drawn as three drives, a draw without the long one (8/27 of the draws) is all 3.0, -33 %:
    the interval is [-33 %, +100 %], undecided. With every frame a drive of its own the draws are
    the frames' own, number for number."""
    stat = (Stat("images.grey_mean", "grey", "", med("images.grey_mean")),)
    sim, real = _one([2.0]), _one([1.0] * 9 + [3.0] * 2)
    (frames,) = intervals(sim, real, stats=stat).values()
    assert frames == Interval(1.0, 1.0) and frames.decides("fail", 0.15)
    long_drive = {str(i): "long" for i in range(9)}
    (whole,) = intervals(sim, real, stats=stat, real_drives=long_drive).values()
    assert whole == Interval(pytest.approx(-1 / 3), 1.0) and not whole.decides("fail", 0.15)
    alone = {str(i): f"drive {i}" for i in range(11)}
    assert intervals(sim, real, stats=stat, real_drives=alone) == {"images.grey_mean": frames}
    assert compare(sim, real, real_drives=long_drive).units == (1, 3)
    assert compare(sim, real).units == (1, 11)


def test_the_real_dev_frames_against_themselves(real_root):
    """Every verdict passes at 0; the points per sweep (115k +- a few %) are decided, the share of
    ground returns left of the sensor (about 0.3 in six frames, 1.0 in four) is not: eleven frames
    cannot tell a median of 0.36 from one of 0.6."""
    real = compute_stats(real_root)
    rows = {r.key: r for r in compare(real, real).rows}
    assert all(r.rel_diff == 0 and r.verdict == "pass" for r in rows.values() if r.verdict != "n/a")
    assert rows["lidar.points_per_sweep"].decided is True
    left = rows["lidar.near_ground_share_left"]
    assert left.decided is False and left.interval.hi > 0.5 and left.interval.lo < -0.15


def test_the_report_lists_the_decided_fails():
    """Real 1.0 and 1.1 against 2: +90 % at the median (1.05), every draw +82 % to +100 %: a decided
    fail, named with its difference; every statistic without values is n/a, never decided."""
    from fidelity.report import _decided_fails

    comp = compare(_one([2.0]), _one([1.0, 1.1]))
    rows = {r.key: r for r in comp.rows}
    assert rows["images.grey_mean"].verdict == "fail" and rows["images.grey_mean"].decided is True
    assert all(r.verdict == "n/a" and r.decided is None for k, r in rows.items() if k != "images.grey_mean")
    assert _decided_fails(comp) == "`images.grey_mean` (+90.5%)"
