"""HDF5 recordings: round trip, files written by plain h5py, groups, time base, bad input."""

import h5py
import numpy as np
import pytest

from impactometer.errors import RecordingError
from impactometer.io import read_recording, write_recording
from impactometer.recording import Recording


def test_written_file_holds_one_dataset_per_channel_with_units(tmp_path):
    rec = Recording(sample_rate=2e3, channels={"contact_force": [1.0, 2.0], "u2": [0.0, 1e-3]},
                    metadata={"mass_kg": 3.0})
    path = write_recording(rec, tmp_path / "run.h5")
    with h5py.File(path, "r") as handle:
        assert sorted(handle) == ["contact_force", "u2"]
        assert handle["contact_force"].attrs["unit"] == "N" and handle["u2"].attrs["unit"] == "m"
        assert handle.attrs["sample_rate"] == 2e3 and '"mass_kg": 3.0' in handle.attrs["metadata"]


def _daq_file(path, *, attrs=None, group="daq", n=100):
    t = np.arange(n) * 1e-5
    with h5py.File(path, "w") as handle:
        g = handle.create_group(group)
        g.create_group("empty")
        g.create_dataset("Force", data=np.sin(t * 1e3)).attrs["units"] = "kN"
        g.create_dataset("Accel", data=np.cos(t * 1e3)).attrs["unit"] = b"g"
        g.create_dataset("status", data=np.array([b"ok"]))
        g.create_dataset("calibration matrix", data=np.eye(3))
        for key, value in (attrs if attrs is not None else {"dt": 1e-5, "t0": -2e-4, "mass_kg": 12.5,
                                                             "operator": "B"}).items():
            g.attrs[key] = value
    return t


def test_foreign_h5py_file_with_group_units_and_dt(tmp_path):
    path = tmp_path / "daq.hdf5"
    t = _daq_file(path)
    rec = read_recording(path)  # the only group with datasets is found
    assert rec.sample_rate == pytest.approx(1e5) and rec.start_time == pytest.approx(-2e-4)
    np.testing.assert_allclose(rec.contact_force, 1e3 * np.sin(t * 1e3))
    np.testing.assert_allclose(rec.piston_acceleration, 9.80665 * np.cos(t * 1e3))
    assert rec.truth("mass_kg") == 12.5 and rec.metadata["operator"] == "B"
    assert read_recording(path, group="daq").sample_rate == rec.sample_rate


def test_time_dataset_gives_the_time_base(tmp_path):
    path = tmp_path / "t.h5"
    with h5py.File(path, "w") as handle:
        handle["time"] = 0.002 + np.arange(50) / 20e3
        handle["Fc"] = np.linspace(0, 1, 50)
    rec = read_recording(path)
    assert rec.sample_rate == pytest.approx(20e3, rel=1e-9) and rec.start_time == pytest.approx(0.002)


@pytest.mark.parametrize("make, kwargs, match", [
    (lambda p: _daq_file(p), dict(group="nope"), r"group 'nope' does not exist; groups found: \['daq'\]"),
    (lambda p: _daq_file(p, attrs={}), {}, "no time column and no sample rate"),
    (lambda p: _daq_file(p, attrs={"dt": 0.0}), {}, r"dt must be a sample period within \[1e-08, 1\] s, got 0.0"),
    (lambda p: _daq_file(p, attrs={"fs": "fast"}), {}, "fs must be a number"),
    (lambda p: _daq_file(p, attrs={"fs": 1e4, "metadata": "{oops"}), {}, "attribute 'metadata' must be valid JSON"),
    (lambda p: h5py.File(p, "w").close(), {}, "no channel datasets in the root"),
    (lambda p: p.write_bytes(b"not an hdf5 file at all"), {}, "not a readable hdf5 file"),
])
def test_bad_hdf5_raises_recording_error(tmp_path, make, kwargs, match):
    path = tmp_path / "bad.h5"
    make(path)
    with pytest.raises(RecordingError, match=match) as info:
        read_recording(path, **kwargs)
    assert str(path) in str(info.value)


def test_datasets_of_different_lengths_are_refused(tmp_path):
    path = tmp_path / "len.h5"
    with h5py.File(path, "w") as handle:
        handle.attrs["sample_rate"] = 1e4
        handle["force"] = np.zeros(10)
        handle["acc"] = np.zeros(12)
    with pytest.raises(RecordingError, match="equal lengths"):
        read_recording(path)
