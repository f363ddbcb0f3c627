"""MATLAB recordings: v5 round trip (scipy.io), files with structs, and v7.3 (HDF5-based) files via h5py."""

import h5py
import numpy as np
import pytest
import scipy.io

from impactometer.errors import RecordingError
from impactometer.io import read_recording, write_recording
from impactometer.recording import Recording


def test_written_v5_file_holds_column_vectors_rate_and_units(tmp_path):
    rec = Recording(sample_rate=5e3, channels={"contact_force": [0.0, 2.0, 1.0], "piston_acceleration":
                                               [0.0, -1.0, 0.5]}, metadata={"mass_kg": 15.0})
    content = scipy.io.loadmat(write_recording(rec, tmp_path / "run.mat"), simplify_cells=True)
    assert np.asarray(content["contact_force"]).shape == (3,) and content["sample_rate"] == 5e3
    assert content["units"] == {"contact_force": "N", "piston_acceleration": "m/s^2"}
    raw = scipy.io.loadmat(tmp_path / "run.mat")
    assert raw["contact_force"].shape == (3, 1)


def test_v5_file_with_a_struct_units_and_fs(tmp_path):
    path = tmp_path / "lab.mat"
    force = np.array([0.0, 0.2, 0.8, 0.5, 0.1])
    scipy.io.savemat(path, {"data": {"force": force, "acc": force * -2}, "units": {"force": "kN", "acc": "g"},
                            "Fs": 25e3, "mass_kg": 9.0, "note": "drop 3"})
    rec = read_recording(path)
    assert rec.sample_rate == 25e3 and rec.truth("mass_kg") == 9.0 and rec.metadata["note"] == "drop 3"
    np.testing.assert_allclose(rec.contact_force, force * 1e3)
    np.testing.assert_allclose(rec.piston_acceleration, force * -2 * 9.80665)
    assert rec.metadata["source_channels"]["contact_force"] == "data.force"


def _v73(path, n=64):
    """A file laid out as MATLAB -v7.3 saves it: 512-byte user block, column vectors stored as (1, n)."""
    with h5py.File(path, "w", userblock_size=512) as handle:
        for name, data in (("time", np.arange(n) / 10e3), ("Fc", np.linspace(0, 5, n)),
                           ("a2", np.linspace(0, -1, n))):
            ds = handle.create_dataset(name, data=data.reshape(1, -1))
            ds.attrs["MATLAB_class"] = np.bytes_("double")
        text = handle.create_dataset("operator", data=np.array([[ord(c)] for c in "lab D"], dtype=np.uint16))
        text.attrs["MATLAB_class"] = np.bytes_("char")
        units = handle.create_group("units")
        units.attrs["MATLAB_class"] = np.bytes_("struct")
        u = units.create_dataset("Fc", data=np.array([[ord(c)] for c in "kN"], dtype=np.uint16))
        u.attrs["MATLAB_class"] = np.bytes_("char")
    with open(path, "r+b") as handle:
        header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
        handle.write(header.ljust(116) + bytes(8) + b"\x00\x02IM")


def test_v73_file_is_read_through_h5py(tmp_path):
    path = tmp_path / "v73.mat"
    _v73(path)
    rec = read_recording(path)
    assert rec.sample_rate == pytest.approx(10e3, rel=1e-9)
    np.testing.assert_allclose(rec.contact_force, np.linspace(0, 5e3, 64))
    np.testing.assert_allclose(rec.piston_acceleration, np.linspace(0, -1, 64))
    assert rec.metadata["operator"] == "lab D"


@pytest.mark.parametrize("content, match", [
    ({"force": np.arange(5.0)}, "no time column and no sample rate"),
    ({"voltage": np.arange(5.0), "fs": 1e3}, r"no contact_force channel .*channels found: \['voltage'\]"),
    ({"force": np.arange(5.0), "fs": -1.0}, r"fs must be a number within \[1, 1e\+08\] Hz"),
    ({"force": np.arange(5.0), "fs": 1e3, "metadata_json": "{x"}, "metadata_json' must be valid JSON"),
    ({"force": np.array([0, np.inf, 1.0]), "fs": 1e3}, r"non-finite sample \(inf\) at index 1"),
])
def test_bad_mat_content_raises_recording_error(tmp_path, content, match):
    path = tmp_path / "bad.mat"
    scipy.io.savemat(path, content)
    with pytest.raises(RecordingError, match=match):
        read_recording(path)


def test_truncated_mat_is_refused(tmp_path):
    rec = Recording(sample_rate=5e3, channels={"contact_force": np.linspace(0, 1, 200)})
    path = write_recording(rec, tmp_path / "ok.mat")
    cut = tmp_path / "cut.mat"
    cut.write_bytes(path.read_bytes()[:300])
    with pytest.raises(RecordingError, match="not a readable mat file"):
        read_recording(cut)
