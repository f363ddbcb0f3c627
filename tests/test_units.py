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


@pytest.mark.parametrize("text, dimension, match", [
    ("200", "pressure", r"^--x 200: a bare number is SI \(Pa\); did you mean 200kPa\? \(write 200Pa to mean it\)$"),
    ("30000", "mass", r"did you mean 30000g\? \(write 30000kg to mean it\)"),
    ("20", "length", r"did you mean 20cm or 20mm\?"),
    ("200", "velocity", r"did you mean 200mm/s\?"),
    ("50", "time", r"did you mean 50ms\?"),
    ("50", "frequency", r"SI \(Hz\); did you mean 50kHz\?"),
    ("2", "fraction", r"a fraction \(2 = 200%\); did you mean 2%\? \(write 200% to mean it\)"),
    ("0.5", "pressure", r"an implausible pressure; give its unit \(write 0.5Pa to mean it\)"),
])
def test_a_bare_number_outside_its_plausible_range_is_refused_on_request(text, dimension, match):
    """A bare number is SI, and on the command line (``plausible=True``) one outside the range a drop test makes
    plausible is refused, naming the unit likely meant and the spelling that keeps the number."""
    assert parse_quantity(text, dimension) == float(text)  # the Python API and files: SI, as before
    with pytest.raises(UnitError, match=match):
        parse_quantity(text, dimension, field="--x", plausible=True)


@pytest.mark.parametrize("text, dimension, expected", [
    ("200Pa", "pressure", 200.0), ("0", "pressure", 0.0), ("2000", "pressure", 2000.0), ("30", "mass", 30.0),
    ("30000g", "mass", 30.0), ("0.2", "length", 0.2), ("20m", "length", 20.0), ("50000", "frequency", 5e4),
    ("0.02", "fraction", 0.02), ("80%", "fraction", 0.8), ("0.05", "time", 0.05), ("-3", "mass", -3.0),
    ("1500", "force", 1500.0),
])
def test_a_unit_or_a_plausible_bare_number_is_taken_as_written(text, dimension, expected):
    """A unit suffix, SI included, is always the user's intent; 0 and negative numbers are left to the checks of
    the quantity; dimensions without a range (force) take any bare number."""
    assert parse_quantity(text, dimension, field="--x", plausible=True) == pytest.approx(expected, rel=1e-15)


def test_every_range_names_units_of_its_dimension():
    from impactometer.units import BARE_RANGES

    for dimension, (low, high, meant) in BARE_RANGES.items():
        assert dimension in UNITS and 0 <= low < high and meant and set(meant) <= set(UNITS[dimension])
