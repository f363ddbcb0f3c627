"""Quantities with unit suffixes, parsed at the edges into SI."""

from __future__ import annotations

import pytest

from impactometer.errors import ParameterError, UnitError
from impactometer.units import UNITS, parse_quantity


@pytest.mark.parametrize("text, dimension, expected", [
    ("200kPa", "pressure", 200e3), ("2 bar", "pressure", 2e5), ("0.4MPa", "pressure", 4e5),
    ("14.5psi", "pressure", 14.5 * 6894.757293168), ("30kg", "mass", 30.0), ("500g", "mass", 0.5),
    ("0.2m", "length", 0.2), ("200 mm", "length", 0.2), ("20cm", "length", 0.2),
    ("2m/s", "velocity", 2.0), ("7.2km/h", "velocity", 2.0), ("50ms", "time", 0.05),
    ("250us", "time", 250e-6), ("50kHz", "frequency", 50e3), ("1e3Hz", "frequency", 1e3),
    ("2%", "fraction", 0.02), ("3g", "acceleration", 3 * 9.80665), ("1.5kN", "force", 1500.0),
    ("+.5 m", "length", 0.5), ("-3kPa", "pressure", -3e3), ("12", "mass", 12.0), (7, "time", 7.0),
])
def test_parse_quantity_to_si(text, dimension, expected):
    assert parse_quantity(text, dimension) == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("text, dimension, match", [
    ("200kpaa", "pressure", r"--pressure: unknown pressure unit 'kpaa' in '200kpaa'; expected one of"),
    ("30kg", "pressure", "unknown pressure unit 'kg'"),
    ("kPa200", "pressure", r"--pressure must be a number with an optional pressure unit \(e.g. 200kPa\)"),
    ("", "pressure", "must be a number"),
    ("nan", "pressure", "must be a finite number"),
    ("infkPa", "pressure", "must be a finite number"),
    ("1.5.3kg", "pressure", "unknown pressure unit"),
    (None, "pressure", "must be a number"),
    (True, "pressure", "must be a number"),
    (float("nan"), "pressure", "must be a finite number"),
])
def test_unparsable_quantities_are_parameter_errors(text, dimension, match):
    with pytest.raises(UnitError, match=match) as info:
        parse_quantity(text, dimension, field="--pressure")
    assert isinstance(info.value, ParameterError)


def test_every_unit_parses_to_its_factor():
    for dimension, units in UNITS.items():
        for symbol, factor in units.items():
            assert parse_quantity("2" + symbol, dimension) == pytest.approx(2 * factor, rel=1e-15), symbol
            same_letters = [u for u in units if u.lower() == symbol.lower() and units[u] != factor]
            if not same_letters:  # case matters only where it tells two units apart
                assert parse_quantity("2" + symbol.upper(), dimension) == pytest.approx(2 * factor, rel=1e-15)
                assert parse_quantity("2" + symbol.lower(), dimension) == pytest.approx(2 * factor, rel=1e-15)


@pytest.mark.parametrize("text, dimension, expected", [
    ("1mHz", "frequency", 1e-3), ("1MHz", "frequency", 1e6), ("2kpa", "pressure", 2e3), ("3mPa", "pressure", 3e-3),
    ("3MPa", "pressure", 3e6), ("2 mbar", "pressure", 200.0), ("5KHZ", "frequency", 5e3),
])
def test_prefixes_are_read_as_written(text, dimension, expected):
    assert parse_quantity(text, dimension) == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("text, dimension", [("1mhz", "frequency"), ("1MHZ", "frequency"), ("2 MPA", "pressure")])
def test_a_spelling_of_two_units_is_refused(text, dimension):
    with pytest.raises(UnitError, match=r"is ambiguous; write \w+ or \w+ \(case tells milli- from mega-\)"):
        parse_quantity(text, dimension, field="--sample-rate")


def test_an_overflowing_quantity_is_refused():
    with pytest.raises(UnitError, match="overflows"):
        parse_quantity("1e308GHz", "frequency")
