"""Format dispatch, overwrite protection, read-only reading and calibration sets."""

import hashlib
import os
import re

import numpy as np
import pytest

from impactometer.errors import RecordingError
from impactometer.io import FORMATS, read_calibration_set, read_recording, write_recording
from impactometer.recording import Recording
from impactometer.rig import Scenario
from impactometer.sensors import record

EXTENSIONS = (".csv", ".h5", ".tdms", ".mat")


@pytest.fixture(scope="module")
def simulated():
    return record(Scenario(mass=30.0, velocity=2.0), duration=0.01, noise=0.02, seed=3, pre_trigger=0.001,
                  extra_channels=["pressure_lower", "piston_displacement"])


@pytest.mark.parametrize("ext", EXTENSIONS)
def test_round_trip_is_exact(tmp_path, simulated, ext):
    back = read_recording(write_recording(simulated, tmp_path / f"run{ext}"))
    assert back.sample_rate == simulated.sample_rate and back.start_time == simulated.start_time
    assert list(back.channels) == list(simulated.channels)
    for name, values in simulated.channels.items():
        np.testing.assert_array_equal(back.channel(name), values)
        assert back.unit(name) == simulated.unit(name)
    for key, value in simulated.metadata.items():
        assert back.metadata[key] == value, key


# MAT files rename channels to MATLAB variables by design; HDF5 refuses "/" (the test below)
@pytest.mark.parametrize("ext, name", [(ext, name) for ext in EXTENSIONS[:3]
                                       for name in ("a,b", "a;b", 'say "hi"', "x/y", "Kraft, gemessen; roh")
                                       if not (ext == ".h5" and "/" in name)])
def test_channel_names_with_separators_and_quotes_come_back(tmp_path, ext, name):
    rec = Recording(sample_rate=1e3, channels={"contact_force": np.arange(3.0), name: np.array([1.0, 2.0, 3.0])})
    back = read_recording(write_recording(rec, tmp_path / f"run{ext}"))
    assert list(back.channels) == [*rec.channels]  # a CSV header cell "a,b" was unquoted: two columns, unreadable
    np.testing.assert_array_equal(back.channel(name), rec.channel(name))


@pytest.mark.parametrize("ext, name, why", [
    (".csv", "a\nb", "control character"), (".csv", "a\rb", "control character"),
    (".h5", "a/b", "HDF5 reads '/' as a path through groups"),  # before: a subgroup, silently left out on reading
    (".h5", ".", "HDF5 reserves '.'"),
    (".tdms", "time", "takes it for the time column"), (".h5", "force [kN]", "takes its end for a unit"),
    (".csv", " force", "strips the spaces"),
])
def test_channel_names_that_cannot_come_back_are_refused_on_writing(tmp_path, ext, name, why):
    rec = Recording(sample_rate=1e3, channels={"contact_force": np.arange(3.0), name: np.array([1.0, 2.0, 3.0])})
    with pytest.raises(RecordingError, match=f"channel {re.escape(repr(name))} cannot be written to .*{why}"):
        write_recording(rec, tmp_path / f"run{ext}")
    assert list(tmp_path.iterdir()) == []


def _rec(mass=None, **extra):
    rng = np.random.default_rng(0)
    metadata = {} if mass is None else {"mass_kg": mass, "velocity_m_s": 2.0}
    return Recording(sample_rate=10e3, channels={"contact_force": rng.random(40),
                                                 "piston_acceleration": rng.normal(size=40)},
                     metadata=metadata | extra)


@pytest.mark.parametrize("ext", EXTENSIONS)
def test_writing_refuses_to_overwrite_unless_asked(tmp_path, ext):
    path = write_recording(_rec(1.0), tmp_path / f"r{ext}")
    before = path.read_bytes()
    with pytest.raises(RecordingError, match="exists; pass overwrite=True"):
        write_recording(_rec(2.0), path)
    assert path.read_bytes() == before
    write_recording(_rec(2.0), path, overwrite=True)
    assert read_recording(path).truth("mass_kg") == 2.0
    assert not [p for p in tmp_path.iterdir() if "partial" in p.name]


def test_csv_sidecar_is_protected_too(tmp_path):
    (tmp_path / "r.json").write_text("{}")
    with pytest.raises(RecordingError, match=r"r\.json' exists"):
        write_recording(_rec(), tmp_path / "r.csv")
    assert not (tmp_path / "r.csv").exists()


@pytest.mark.parametrize("ext", EXTENSIONS)
def test_reading_never_modifies_the_file(tmp_path, ext):
    path = write_recording(_rec(3.0), tmp_path / f"r{ext}")
    stamp = os.stat(path).st_mtime_ns
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    listing = sorted(p.name for p in tmp_path.iterdir())
    read_recording(path)
    assert os.stat(path).st_mtime_ns == stamp
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest
    assert sorted(p.name for p in tmp_path.iterdir()) == listing


def test_unknown_extension_missing_file_and_bad_options(tmp_path):
    with pytest.raises(RecordingError, match=r"unknown extension '\.xlsx'; expected one of \.csv"):
        read_recording(tmp_path / "r.xlsx")
    with pytest.raises(RecordingError, match="unknown extension"):
        write_recording(_rec(), tmp_path / "r.bin")
    with pytest.raises(RecordingError, match="no such file"):
        read_recording(tmp_path / "missing.csv")
    path = write_recording(_rec(), tmp_path / "r.csv")
    with pytest.raises(RecordingError, match="group='g' applies to HDF5 and TDMS files only"):
        read_recording(path, group="g")
    with pytest.raises(RecordingError, match="flip_force must be True or False"):
        read_recording(path, flip_force="yes")
    with pytest.raises(RecordingError, match="folder .* does not exist"):
        write_recording(_rec(), tmp_path / "nowhere" / "r.csv")
    assert set(FORMATS.values()) == {"csv", "hdf5", "tdms", "mat"}


def test_calibration_set_with_a_manifest_completing_metadata(tmp_path):
    write_recording(_rec(5.0), tmp_path / "a.csv")
    write_recording(_rec(6.0), tmp_path / "b.h5")
    write_recording(_rec(), tmp_path / "c.tdms")
    (tmp_path / "manifest.csv").write_text("file,mass_kg,velocity_m_s,pressure_gauge_Pa\n"
                                           "b.h5,6.02,2,150000\nc.tdms,7,1.25,\n")
    recs = read_calibration_set(tmp_path)
    assert [r.source.rsplit("/", 1)[-1] for r in recs] == ["a.csv", "b.h5", "c.tdms"]
    assert [r.truth("mass_kg") for r in recs] == [5.0, 6.02, 7.0]  # a manifest may round what a file states
    assert [r.truth("velocity_m_s") for r in recs] == [2.0, 2.0, 1.25]
    assert recs[1].truth("pressure_gauge_Pa") == 150000.0 and recs[2].truth("pressure_gauge_Pa") is None


def test_manifest_contradicting_a_file_is_refused(tmp_path):
    """A manifest with its mass and velocity columns swapped would otherwise override every file silently."""
    write_recording(_rec(30.0), tmp_path / "a.h5")
    (tmp_path / "manifest.csv").write_text("file,mass_kg,velocity_m_s\na.h5,2,3\n")
    with pytest.raises(RecordingError, match=r"a.h5: the truth mass_kg is stated twice, differently: the file's "
                                             r"mass_kg gives 30 kg, the manifest's mass_kg gives 2 kg"):
        read_calibration_set(tmp_path)


def test_explicit_manifest_outside_the_folder(tmp_path):
    folder = tmp_path / "set"
    folder.mkdir()
    write_recording(_rec(), folder / "a.mat")
    manifest = tmp_path / "truth.csv"
    manifest.write_text("file,mass_kg,velocity_m_s\na.mat,8,2.5\n")
    (rec,) = read_calibration_set(folder, manifest)
    assert rec.truth("mass_kg") == 8.0


@pytest.mark.parametrize("manifest, match", [
    ("file,mass_kg\na.csv,3\n", r"lacks column\(s\) \['velocity_m_s'\]"),
    ("file,mass_kg,velocity_m_s\na.csv,heavy,2\n", "line 2: metadata mass_kg must be a number with an optional "
                                                   "mass unit"),
    ("file,mass_kg,velocity_m_s\na.csv,-3,2\n", r"metadata mass_kg must be within \[0, 10000\] kg"),
    ("file,mass_kg,velocity_m_s\na.csv,30,nan\n", "metadata velocity_m_s must be a finite number"),
    ("file,mass_kg,velocity_m_s\na.csv,2,30\n", r"metadata velocity_m_s must be within \[0, 15.3\d*\] m/s"),
    ("file,mass_kg,velocity_m_s\nz.csv,3,2\n", r"file\(s\) \['z.csv'\] not found"),
    ("file,mass_kg,velocity_m_s\na.csv,3,2\na.csv,3,2\n", "distinct non-empty name"),
    ("file,mass_kg,velocity_m_s\n", "manifest has no rows"),
])
def test_bad_manifest(tmp_path, manifest, match):
    write_recording(_rec(), tmp_path / "a.csv")
    (tmp_path / "manifest.csv").write_text(manifest)
    with pytest.raises(RecordingError, match=match):
        read_calibration_set(tmp_path)


def test_empty_or_missing_folder(tmp_path):
    with pytest.raises(RecordingError, match="no recordings"):
        read_calibration_set(tmp_path)
    with pytest.raises(RecordingError, match="not a folder"):
        read_calibration_set(tmp_path / "none")
    write_recording(_rec(), tmp_path / "a.csv")
    with pytest.raises(RecordingError, match="manifest does not exist"):
        read_calibration_set(tmp_path, tmp_path / "m.csv")
