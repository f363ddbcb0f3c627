"""TDMS recordings: round trip and files laid out as LabVIEW writes them (written here with npTDMS)."""

import numpy as np
import pytest
from nptdms import ChannelObject, GroupObject, RootObject, TdmsFile, TdmsWriter

from impactometer.errors import RecordingError
from impactometer.io import read_recording, write_recording
from impactometer.recording import Recording


def test_written_file_is_labview_shaped(tmp_path):
    rec = Recording(sample_rate=50e3, channels={"contact_force": [0.0, 5.0, 2.0]}, start_time=-1e-3,
                    metadata={"mass_kg": 40.0, "seed": 5})
    tdms = TdmsFile.read(write_recording(rec, tmp_path / "run.tdms"))
    channel = tdms["Recording"]["contact_force"]
    assert channel.properties["unit_string"] == "N"
    assert channel.properties["wf_increment"] == pytest.approx(1 / 50e3)
    assert channel.properties["wf_start_offset"] == pytest.approx(-1e-3)
    assert channel.properties["wf_samples"] == 3
    assert tdms.properties["mass_kg"] == 40.0
    np.testing.assert_array_equal(channel[:], rec.contact_force)


def _labview_file(path, *, increments=(2e-5, 2e-5), extra_groups=("Settings",), n=200):
    t = np.arange(n) * 2e-5
    objects = [RootObject(properties={"name": "drop 17", "mass_kg": 18.0, "Operator": "C"})]
    for g in extra_groups:
        objects += [GroupObject(g, properties={"Gain": 2.0}),
                    ChannelObject(g, "Setpoint", np.arange(3.0), properties={"unit_string": "V"})]
    objects.append(GroupObject("Measurement", properties={"velocity_m_s": 1.2}))
    for name, data, unit, dt in (("Force", np.sin(t * 500), "kN", increments[0]),
                                 ("Acceleration", -np.cos(t * 500), "g", increments[1])):
        objects.append(ChannelObject("Measurement", name, data, properties={
            "wf_increment": dt, "wf_start_offset": -4e-4, "wf_samples": n, "unit_string": unit}))
    objects.append(ChannelObject("Measurement", "Comment", np.array(["a", "b"])))
    with TdmsWriter(str(path)) as writer:
        writer.write_segment(objects)
    return t


def test_labview_style_file_is_read_with_units_and_metadata(tmp_path):
    path = tmp_path / "drop17.tdms"
    t = _labview_file(path)
    rec = read_recording(path)  # the group holding a force channel is picked
    assert rec.sample_rate == pytest.approx(50e3) and rec.start_time == pytest.approx(-4e-4)
    np.testing.assert_allclose(rec.contact_force, 1e3 * np.sin(t * 500))
    np.testing.assert_allclose(rec.piston_acceleration, -9.80665 * np.cos(t * 500))
    assert rec.truth("mass_kg") == 18.0 and rec.truth("velocity_m_s") == 1.2 and rec.metadata["Operator"] == "C"
    assert sorted(rec.channels) == ["contact_force", "piston_acceleration"]
    assert read_recording(path, group="Measurement").sample_rate == rec.sample_rate


def test_missing_group_lists_the_groups(tmp_path):
    path = tmp_path / "g.tdms"
    _labview_file(path)
    with pytest.raises(RecordingError, match=r"TDMS group 'Data' does not exist; groups found: \['Settings', "
                                             r"'Measurement'\]"):
        read_recording(path, group="Data")
    with pytest.raises(RecordingError, match="holds no numeric channel|no contact_force channel"):
        read_recording(path, group="Settings")


def test_channels_with_different_increments_are_refused(tmp_path):
    path = tmp_path / "inc.tdms"
    _labview_file(path, increments=(2e-5, 1e-5))
    with pytest.raises(RecordingError, match="different wf_increment"):
        read_recording(path)


def test_random_bytes_are_refused(tmp_path):
    path = tmp_path / "x.tdms"
    path.write_bytes(b"TDSm" + bytes(range(200)))
    with pytest.raises(RecordingError, match="not a readable tdms file|no TDMS groups found"):
        read_recording(path)
    path.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(RecordingError, match="not a readable tdms file"):
        read_recording(path)
