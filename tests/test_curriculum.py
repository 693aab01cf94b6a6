"""curriculum.py: Eq. 16 below, inside and above the window [0.5, 0.7], clipping, the ablation's schedules."""
import numpy as np
import pytest

import curriculum as cur


def run(c, outcomes):
    return [c.update(s) for s in outcomes]


def test_rises_above_window_by_half_a_millimetre():
    c = cur.Curriculum("adaptive", final=0.020)
    assert c.ranges() == (0.0, 0.0)
    run(c, [True] * 4)                               # sr = 1 > 0.7: +eps each episode
    assert c.delta == pytest.approx(4 * 0.0005 / 0.020)
    e_r, ex_r = c.ranges()
    assert e_r == pytest.approx(0.002) and ex_r == pytest.approx(0.002)


def test_holds_inside_window_and_falls_below():
    c = cur.Curriculum("adaptive", final=0.020)
    c.delta = 0.5
    run(c, [True, False] * 7 + [True])               # 8 of 15 = 0.533, inside [0.5, 0.7]
    assert c.success_rate == pytest.approx(8 / 15)
    d = c.delta
    c.update(False)                                  # 7 of 15 = 0.467 < 0.5: -eps
    assert c.delta == pytest.approx(d - 0.025)
    c.update(True)                                   # 8 of 15 again: hold
    assert c.delta == pytest.approx(d - 0.025)
    # the edges as Eq. 16 is written: sr = 0.5 is not above alpha but is below beta -> falls;
    # sr = 0.7 is above alpha and not below beta -> rises
    for sr, step in ((0.5, -1), (0.7, +1)):
        c2 = cur.Curriculum("adaptive", final=0.020, history=10)
        c2.delta = 0.5
        run(c2, [True] * int(sr * 10) + [False] * (10 - int(sr * 10)))
        assert c2.success_rate == pytest.approx(sr)
        before = c2.delta
        c2.update(c2.successes[0])                  # the window keeps the same rate
        assert c2.delta == pytest.approx(before + step * 0.025)


def test_clips_at_zero_and_one():
    c = cur.Curriculum("adaptive", final=0.020)
    run(c, [False] * 20)
    assert c.delta == 0.0 and c.ranges() == (0.0, 0.0)
    run(c, [True] * 100)
    assert c.delta == 1.0 and c.ranges() == (pytest.approx(0.020), pytest.approx(0.020))


def test_fixed_schedules_of_the_ablation():
    none = cur.Curriculum("none", final=0.030)
    run(none, [False] * 20)
    assert none.ranges() == (0.030, 0.030)
    c30 = cur.Curriculum("g2-c30", final=0.030)
    assert c30.ranges() == (pytest.approx(0.002), 0.030)
    c10 = cur.Curriculum("g2-c10", final=0.030)
    assert c10.ranges() == (pytest.approx(0.002), 0.010)
    run(c10, [True] * 30)                            # E_r grows past 10 mm, Ex_r follows it
    e_r, ex_r = c10.ranges()
    assert e_r > 0.010 and ex_r == pytest.approx(e_r)
    c2 = cur.Curriculum("g2-c2", final=0.030)
    assert c2.ranges() == (pytest.approx(0.002), pytest.approx(0.002))
    ex10 = cur.Curriculum("ex10", final=0.020)        # the observation ablation: Ex_r stays at 10 mm
    assert ex10.ranges() == (0.0, 0.010)
    run(ex10, [True] * 100)
    assert ex10.ranges() == (pytest.approx(0.020), 0.010)


def test_state_round_trip_and_mismatch():
    c = cur.Curriculum("adaptive", final=0.020)
    run(c, list(np.random.default_rng(0).random(30) < 0.8))
    d = c.state_dict()
    c2 = cur.Curriculum("adaptive", final=0.020)
    c2.load_state_dict(d)
    assert c2.delta == c.delta and list(c2.successes) == list(c.successes)
    with pytest.raises(ValueError):
        cur.Curriculum("g2-c2", final=0.020).load_state_dict(d)
    with pytest.raises(ValueError):
        cur.Curriculum("sometimes")
