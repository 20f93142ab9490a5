"""Attractor recognition on maps whose attractors are known exactly.

The recogniser sees only section points, so exact maps stand in for the stroboscopic map:
a contraction onto a fixed point (distance halves each period: inside a tolerance of
2**-7 after exactly 7 periods), a period-2 orbit, and a rotation of a circle by the golden
ratio (a torus section: every phase lies on the attractor).
"""

import math

import numpy as np
import pytest

from rubcli.analysis.sweep.attractors import (
    DIVERGED,
    AttractorSet,
    Recogniser,
    describe,
)

CENTRE = np.array([0.4, -0.2, 0.1, 0.3])
GOLDEN = (math.sqrt(5) - 1) / 2


def contraction(start, centre, n):
    """x_k = centre + 2**-k (start - centre), k = 1 ... n."""
    k = np.arange(1, n + 1)[:, None]
    return centre + (np.asarray(start) - centre) * 0.5**k


def circle(n, radius=2.0, phase=0.0):
    angle = 2 * math.pi * (phase + GOLDEN * np.arange(n))
    c, s = np.cos(angle), np.sin(angle)
    return np.column_stack([radius * c, radius * s, -radius * s, radius * c])


def feed_all(recogniser, points):
    for period, point in enumerate(points, start=1):
        label = recogniser.feed(point, period)
        if label is not None:
            return label, period
    return None, len(points)


def test_a_contraction_is_recognised_when_it_enters_the_tolerance():
    known = AttractorSet(tolerance=2.0**-7 * 1.000001, consecutive=5)
    assert known.learn(contraction(CENTRE + 1.0, CENTRE, 60)[-20:]) == 0
    start = CENTRE + np.array([1.0, 0.0, 0.0, 0.0])  # distance 1, halved every period
    recogniser = Recogniser(known)
    label, stopped = feed_all(recogniser, contraction(start, CENTRE, 60))
    assert label == 0
    assert recogniser.run_start == 7  # 2**-7 is the first distance within the tolerance
    assert stopped == 7 + 5 - 1  # and the run of 5 is complete four periods later
    assert known.attractors[0].descriptor["kind"] == "fixed point"


def test_a_period_two_orbit_is_described_and_recognised_from_either_phase():
    a, b = np.array([1.0, 0.0, 0.0, 1.0]), np.array([-1.0, 0.0, 0.0, -1.0])
    orbit = np.array([a, b] * 10)
    known = AttractorSet(tolerance=1e-3, consecutive=4)
    label = known.learn(orbit)
    assert known.attractors[label].descriptor["period"] == 2
    assert known.attractors[label].descriptor["kind"] == "period-2 orbit"
    assert feed_all(Recogniser(known), orbit[1:] + 1e-4)[0] == label


def test_a_torus_is_covered_between_its_samples_and_its_neighbourhood_is_not():
    known = AttractorSet(tolerance=1e-3, consecutive=8)
    label = known.learn(circle(300))
    attractor = known.attractors[label]
    assert attractor.descriptor["kind"] == "torus or chaotic set"
    assert attractor.radius > known.tolerance  # the gap between samples, not the tolerance
    # the same circle at phases never sampled lies on it ...
    assert feed_all(Recogniser(known), circle(50, phase=0.123456))[0] == label
    # ... a circle 10 % larger does not
    assert feed_all(Recogniser(known), circle(50, radius=2.2))[0] is None
    assert known.attractors[label].descriptor["z_max"] == pytest.approx(2.0)


def test_an_attractor_seen_first_is_not_recognised_and_is_learned_once():
    known = AttractorSet(tolerance=1e-2, consecutive=5)
    first = known.learn(contraction(CENTRE + 1, CENTRE, 60)[-20:])
    other = -CENTRE
    label, periods = feed_all(Recogniser(known), contraction(other + 1, other, 40))
    assert label is None and periods == 40  # runs to its budget
    second = known.learn(contraction(other + 1, other, 60)[-20:])
    assert second == first + 1
    # the same attractor's tail from another start is the same attractor, not a third
    assert known.learn(contraction(other - 3, other, 80)[-20:]) == second
    assert len(known.attractors) == 2
    assert feed_all(Recogniser(known), contraction(other + 1, other, 40))[0] == second


def test_divergence_is_recognised_at_once():
    known = AttractorSet(escape_radius=100.0)
    recogniser = Recogniser(known)
    assert recogniser.feed(np.array([1.0, 0, 0, 0]), 1) is None
    assert recogniser.feed(np.array([1e3, 0, 0, 0]), 2) == DIVERGED
    assert recogniser.feed(np.array([np.nan, 0, 0, 0]), 3) == DIVERGED


def test_a_transient_that_leaves_before_the_run_is_complete_is_not_recognised():
    known = AttractorSet(tolerance=1e-2, consecutive=6)
    known.learn(np.tile(CENTRE, (10, 1)))
    near = [CENTRE] * 5 + [CENTRE + 1.0] + [CENTRE] * 5  # 5 on it, one away, 5 on it
    assert feed_all(Recogniser(known), np.array(near))[0] is None


@pytest.mark.parametrize(
    "settings", [{"tolerance": 0.0}, {"tolerance": math.nan}, {"consecutive": 0},
                 {"consecutive": 2.5}, {"escape_radius": math.inf}]
)  # fmt: skip
def test_bad_settings_are_refused(settings):
    with pytest.raises(ValueError):
        AttractorSet(**settings)


def test_describe_on_a_single_point():
    d = describe(np.array([[3.0, 4.0, 0.0, 0.0]] * 3), 1e-6)
    assert d["kind"] == "fixed point" and d["z_min"] == d["z_max"] == 5.0
