"""Response maps in HDF5: round trip, no silent overwrite, and every kind of bad file refused with the reason."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from impactometer.errors import ParameterError, ResponseMapError
from impactometer.identify.response_map import identify_features, load_map, save_map
from test_response_map import polynomial_features, polynomial_map


@pytest.fixture
def saved(tmp_path):
    path = tmp_path / "map.h5"
    save_map(polynomial_map(pressures=(100e3, 300e3)), path)
    return path


def test_round_trip_keeps_everything(saved):
    original = polynomial_map(pressures=(100e3, 300e3))
    loaded = load_map(saved)
    for name in ("masses", "velocities", "pressures_gauge", "values"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(original, name))
    assert loaded.feature_set == original.feature_set
    assert loaded.feature_params == original.feature_params
    assert loaded.sample_rate == original.sample_rate
    assert loaded.rig == original.rig
    assert loaded.stand.contact.law == "hysteretic"  # the built-in stand's pad
    y = polynomial_features(31.0, 2.2, 0.5)
    a = identify_features(y, original, pressure_gauge=200e3)
    b = identify_features(y, loaded, pressure_gauge=200e3)
    assert (a.mass, a.velocity) == (b.mass, b.velocity)


def test_existing_file_is_not_overwritten(saved):
    before = saved.read_bytes()
    with pytest.raises(ParameterError, match="exists; pass overwrite=True"):
        save_map(polynomial_map(), saved)
    assert saved.read_bytes() == before
    save_map(polynomial_map(), saved, overwrite=True)
    assert load_map(saved).pressures_gauge.size == 1


def _edit(path, change):
    with h5py.File(path, "r+") as h5:
        change(h5)


@pytest.mark.parametrize("change, message", [
    (lambda h5: h5.attrs.__setitem__("schema_version", 0), "schema version 0, this impactometer reads version 1"),
    (lambda h5: h5.attrs.__setitem__("schema", "something-else"), "is not 'impactometer-response-map'"),
    (lambda h5: h5.__delitem__("values"), r"missing \['values'\]"),
    (lambda h5: h5.attrs.__delitem__("rig"), r"missing \['rig'\]"),
    (lambda h5: h5.attrs.__setitem__("rig", "{not json"), "attribute 'rig' is not valid JSON"),
    (lambda h5: h5.attrs.__setitem__("feature_set", "fft"), "features must be one of"),
    (lambda h5: h5.attrs.__setitem__("feature_labels", json.dumps(["a", "b"])), "do not match feature set"),
    (lambda h5: h5.attrs.__setitem__("feature_params", json.dumps({"window": -3})), "window must be a number"),
    (lambda h5: h5.attrs.__setitem__("rig", json.dumps({"cylinder": {"bore": "wide"}})),
     "stand description is invalid"),
    (lambda h5: h5.attrs.__setitem__("schema_version", "abc"), "'schema_version' must be a finite number, got abc"),
    (lambda h5: h5.attrs.__setitem__("schema_version", np.nan), "'schema_version' must be a finite number"),
    (lambda h5: h5.attrs.__setitem__("schema_version", np.arange(3)), "'schema_version' must be a finite number"),
    (lambda h5: h5.attrs.__setitem__("sample_rate", "50k"), "'sample_rate' must be a finite number, got 50k"),
    (lambda h5: h5.attrs.__setitem__("sample_rate", np.ones(2)), "'sample_rate' must be a finite number"),
    (lambda h5: h5.attrs.__setitem__("sample_rate", 1e300), r"'sample_rate' must be a number within \[1, 1e\+08\]"),
    (lambda h5: h5.attrs.__setitem__("rig", "[" * 100_000), "attribute 'rig' is not valid JSON"),
    (lambda h5: (h5.__delitem__("masses"), h5.create_dataset("masses", data=np.array([10.0, 5.0, 20.0]))),
     "masses must be a non-empty, finite, strictly increasing axis \\[kg\\], got 5 after 10 at index 1 of 3$"),
    (lambda h5: (h5.__delitem__("masses"), h5.create_dataset("masses", data=np.array([b"a", b"b"]))),
     "'masses' must be a numeric dataset"),
])
def test_damaged_files_are_refused_with_the_reason(saved, change, message):
    _edit(saved, change)
    with pytest.raises(ResponseMapError, match=message):
        load_map(saved)


def test_a_byte_flipped_file_is_refused_in_one_line(saved):
    raw = bytearray(saved.read_bytes())
    original = load_map(saved)
    outcomes = set()
    for position in range(0, len(raw), max(1, len(raw) // 97)):  # one flipped byte at a time, across the file
        flipped = bytearray(raw)
        flipped[position] ^= 0xFF
        saved.write_bytes(bytes(flipped))
        try:
            loaded = load_map(saved)
            for name in ("masses", "velocities", "pressures_gauge", "values"):  # a padding byte: nothing changed
                np.testing.assert_array_equal(getattr(loaded, name), getattr(original, name))
            assert loaded.rig == original.rig and loaded.feature_params == original.feature_params
            outcomes.add("read")
        except ResponseMapError as exc:
            assert "\n" not in str(exc)
            outcomes.add("refused")
    assert "refused" in outcomes


def test_an_edit_that_keeps_the_file_valid_breaks_its_checksum(saved):
    _edit(saved, lambda h5: h5["values"].__setitem__((0, 0, 0, 0), 2.0 * h5["values"][0, 0, 0, 0]))
    with pytest.raises(ResponseMapError, match="does not match its checksum; the file was damaged or edited"):
        load_map(saved)


def test_values_of_the_wrong_shape_or_sign_are_refused(saved):
    _edit(saved, lambda h5: (h5.__delitem__("masses"), h5.create_dataset("masses", data=np.arange(3.0) + 10)))
    with pytest.raises(ResponseMapError, match="must have shape"):
        load_map(saved)


def test_non_hdf5_and_missing_files_are_refused(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"\x89HDF not really" * 10)
    with pytest.raises(ResponseMapError, match="not an HDF5 file"):
        load_map(junk)
    with pytest.raises(ResponseMapError, match="no such map file"):
        load_map(tmp_path / "absent.h5")
