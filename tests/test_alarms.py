"""The alarm rule: a margin of z standard deviations, persistence and hysteresis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid.errors import ConfigError
from servoid.ident.monitoring.alarms import AlarmRule, Alarms, Bound

DZ = Bound(quantity="dead_zone", low=0.9, high=1.1, label="dead zone", unit="rad")


def feed(alarms: Alarms, values, std=0.0, start=0, every=100):
    events = []
    for i, v in enumerate(values):
        events += alarms.check(start + i * every, {"dead_zone": (v, std)})
    return events


def test_an_alarm_needs_persist_checks_beyond_the_bound():
    alarms = Alarms([DZ], AlarmRule(persist=3, z=0.0))
    assert feed(alarms, [1.0, 1.2, 1.2, 1.0, 1.2, 1.2, 1.0]) == []  # never three in a row
    events = feed(alarms, [1.2, 1.2, 1.2], start=1000)
    assert len(events) == 1
    e = events[0]
    assert e.raised and e.side == "above" and e.sample == 1200 and e.since == 1000 and e.limit == 1.1
    assert feed(alarms, [1.3] * 5, start=2000) == []  # raised once, not again
    assert set(alarms.active) == {"dead_zone"}
    assert "ALARM dead zone = 1.2 rad is above its bound 1.1 rad (since sample 1000" in e.message()


def test_the_margin_is_z_standard_deviations():
    alarms = Alarms([DZ], AlarmRule(persist=1, z=2.0))
    assert feed(alarms, [1.15], std=0.03) == []  # 1.15 - 2 x 0.03 = 1.09: not surely out
    (e,) = feed(alarms, [1.15], std=0.02)  # 1.11 > 1.1
    assert e.raised and e.std == 0.02 and "(+/- 0.02)" in e.message()
    below = Alarms([DZ], AlarmRule(persist=1, z=2.0))
    (e,) = feed(below, [0.8], std=0.01)
    assert e.side == "below" and e.limit == 0.9


def test_clearing_needs_the_value_back_inside_by_the_hysteresis():
    alarms = Alarms([DZ], AlarmRule(persist=2, z=0.0, hysteresis=0.1))  # back inside by 0.02
    feed(alarms, [1.2, 1.2])
    assert feed(alarms, [1.09, 1.09, 1.09]) == []  # inside the bound, not inside the clear band
    (e,) = feed(alarms, [1.07, 1.07], start=500)
    assert not e.raised and e.sample == 600 and e.since == 500 and "cleared dead zone" in e.message()
    assert alarms.active == {}


def test_nan_changes_nothing_and_unbounded_quantities_are_ignored():
    alarms = Alarms([Bound(quantity="fit", high=0.1)], AlarmRule(persist=2))
    assert alarms.check(0, {"fit": (0.2, math.nan)}) == []
    assert alarms.check(1, {"fit": (math.nan, 0.0)}) == []  # the run is not broken by an unknown value
    (e,) = alarms.check(2, {"fit": (0.2, 0.0), "m2": (99.0, 0.0)})
    assert e.raised and e.bound.describe() == "<= 0.1"


def test_noise_around_the_bound_raises_far_less_with_margin_and_persistence():
    # an estimate scattering with std 0.01 around 1.085, 1.5 std inside the bound
    values = 1.085 + 0.01 * np.random.default_rng(0).standard_normal(5000)
    raw = Alarms([DZ], AlarmRule(persist=1, z=0.0))
    rule = Alarms([DZ], AlarmRule())
    raw_raised = sum(e.raised for e in feed(raw, values, std=0.01))
    assert raw_raised > 50
    assert sum(e.raised for e in feed(rule, values, std=0.01)) == 0


@pytest.mark.parametrize(
    "make, fragment",
    [
        (lambda: Bound(quantity="dead_zone", low=1.0, high=0.5), "low < high"),
        (lambda: Bound(quantity="dead_zone"), "at least one finite bound"),
        (lambda: Bound(quantity="m2", low=float("nan"), high=2.0), "m2 low"),
        (lambda: AlarmRule(persist=0), "persist"),
        (lambda: AlarmRule(hysteresis=0.5), "hysteresis"),
        (lambda: Alarms([DZ, DZ]), "one bound per quantity"),
    ],
)
def test_bad_rules_are_named(make, fragment):
    with pytest.raises(ConfigError, match=fragment):
        make()
