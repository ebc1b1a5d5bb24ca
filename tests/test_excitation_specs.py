"""Excitation specs: the text form round-trips, and a bad spec is one line naming what is wrong and what is valid."""

import math

import pytest
from hypothesis import given, settings
from test_excitation_signals import specs

from servoid.errors import ConfigError
from servoid.excitation import KINDS, MultisineSpec, PRBSSpec, format_spec, parse_spec


@settings(max_examples=100, deadline=None)
@given(spec=specs())
def test_format_then_parse_gives_the_same_spec(spec):
    assert parse_spec(format_spec(spec)) == spec


def test_parse_reads_the_issue_examples():
    prbs = parse_spec("prbs:amplitude=1.5,hold=3")
    assert prbs == PRBSSpec(amplitude=1.5, hold=3)
    assert (prbs.offset, prbs.rate, prbs.order) == (0.0, math.inf, 10)
    multi = parse_spec("multisine:amplitude=2,bands=0.01-0.2")
    assert multi == MultisineSpec(amplitude=2.0, bands=((0.01, 0.2),))
    assert parse_spec(" Steps : amplitude = 2 , rate=0.5 ").rate == 0.5
    assert parse_spec("multisine:amplitude=1,bands=1e-3-0.05+0.1-0.2").bands == ((0.001, 0.05), (0.1, 0.2))


@pytest.mark.parametrize(
    "text, fragments",
    [
        ("sine:amplitude=1", ["unknown excitation kind 'sine'", *KINDS]),
        ("prbs", ["amplitude is required", "prbs keys: amplitude, offset, rate, hold, order"]),
        ("prbs:amplitude=1,hld=3", ["unknown key 'hld'", "prbs keys:"]),
        ("prbs:amplitude=1,hold=2.5", ["hold (='2.5') must be an integer"]),
        ("prbs:amplitude=-1", ["amplitude (=-1.0) must be > 0"]),
        ("uniform:amplitude=1,rate=0", ["rate (=0.0) must be > 0"]),
        ("uniform:amplitude=1,amplitude=2", ["given twice"]),
        ("uniform:amplitude", ["must be key=value"]),
        ("prbs:amplitude=1,order=30", ["order (=30) must be <= 20"]),
        ("steps:amplitude=1,levels=1", ["levels (=1)"]),
        ("multisine:amplitude=1,bands=0.2-0.1", ["0 < low < high <= 0.5"]),
        ("multisine:amplitude=1,bands=abc", ["bands (='abc')"]),
        ("multisine:amplitude=1,bands=0.0001-0.0002", ["no harmonic", "lengthen the period"]),
        ("chirp:amplitude=1,f1=0.7", ["f1 (=0.7) must lie in [0, 0.5]"]),
        ("chirp:amplitude=1,f0=0,sweep=log", ["log sweep needs f0 and f1 > 0"]),
        ("chirp:amplitude=1,sweep=cubic", ["sweep (='cubic')"]),
        ("levels:amplitude=1,dither=1", ["dither (=1) must be < amplitude"]),
        ("uniform:amplitude=nan", ["amplitude (=nan) must be finite"]),
        ("gentle:amplitude=1,spread=0.5", ["spread (=0.5) must be >= 1"]),
        ("gentle:amplitude=1,smallest=0", ["smallest (=0.0) must lie in (0, 1]"]),
        ("gentle:amplitude=1,accel=-1", ["accel (=-1.0) must be > 0"]),
    ],
)
def test_a_bad_spec_is_one_line_naming_the_problem(text, fragments):
    with pytest.raises(ConfigError) as info:
        parse_spec(text)
    message = str(info.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message


def test_specs_are_keyword_only_and_validated_in_python_too():
    with pytest.raises(TypeError):
        PRBSSpec(1.5)  # type: ignore[misc]
    with pytest.raises(ConfigError, match="hold"):
        PRBSSpec(amplitude=1.0, hold=0)
