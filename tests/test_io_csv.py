"""CSV recordings: round trip, spreadsheet exports, units in headers, sidecars, bad input."""

import json
from pathlib import Path

import numpy as np
import pytest

from impactometer.errors import RecordingError
from impactometer.io import read_recording, write_recording
from impactometer.recording import Recording

DATA = Path(__file__).parent / "data"
G = 9.80665


def test_written_header_names_the_si_units(tmp_path):
    rec = Recording(sample_rate=1e3, channels={"contact_force": [1.0, 2.0], "piston_acceleration": [0.0, 1.0],
                                               "pressure_lower": [3e5, 3e5]})
    path = write_recording(rec, tmp_path / "run.csv")
    assert (tmp_path / "run.json").is_file()
    header = path.read_text().splitlines()[0]
    assert header == "time [s],contact_force [N],piston_acceleration [m/s^2],pressure_lower [Pa]"


def test_spreadsheet_export_with_semicolons_decimal_commas_and_units():
    rec = read_recording(DATA / "spreadsheet_semicolon.csv")
    assert rec.sample_rate == pytest.approx(50e3, rel=1e-9)
    assert rec.start_time == 0.0
    np.testing.assert_allclose(rec.contact_force, [0, 150, 600, 1200, 1050, 300], rtol=1e-12)
    np.testing.assert_allclose(rec.piston_acceleration, np.array([0, 0.5, 2, 4, 3.5, 1]) * G, rtol=1e-12)
    np.testing.assert_allclose(rec.channel("Temperature"), [21.5, 21.5, 21.5, 21.6, 21.6, 21.6])
    assert rec.metadata["channel_units"] == {"Temperature": "degC"}
    assert rec.metadata["source_channels"]["contact_force"] == "Force [kN]"


@pytest.mark.parametrize("separator", [";", "\t"])
def test_decimal_commas_are_found_beyond_a_first_row_of_whole_numbers(tmp_path, separator):
    # the decimal style was decided from the first data row alone: "0;0;0" holds no comma, and the next row,
    # "0,00002;1,5;0,1", was refused
    rows = ["time [s];force [N];acc [m/s^2]", "0;0;0", "0,00002;1,5;0,1", "0,00004;2;0,25"]
    path = tmp_path / "export.csv"
    path.write_text("\n".join(rows).replace(";", separator) + "\n")
    rec = read_recording(path)
    assert rec.sample_rate == pytest.approx(50e3)
    np.testing.assert_allclose(rec.contact_force, [0.0, 1.5, 2.0])
    np.testing.assert_allclose(rec.piston_acceleration, [0.0, 0.1, 0.25])


def test_plain_csv_without_time_takes_the_rate_from_the_sidecar_or_the_option(tmp_path):
    rec = read_recording(DATA / "plain_no_time.csv")
    assert rec.sample_rate == 20e3 and rec.truth("mass_kg") == 25.0 and rec.metadata["operator"] == "lab A"
    np.testing.assert_allclose(rec.contact_force, [0, 100.5, 250, 120, 0])
    alone = tmp_path / "alone.csv"
    alone.write_text((DATA / "plain_no_time.csv").read_text())
    with pytest.raises(RecordingError, match="no time column and no sample rate"):
        read_recording(alone)
    assert read_recording(alone, sample_rate=10e3).sample_rate == 10e3


@pytest.mark.parametrize("header, time_unit, force_scale, acc_scale", [
    ("t [s],Force (N),Acceleration [m/s²]", 1.0, 1.0, 1.0),
    ("Time [us],Fc [kN],a2 [m/s^2]", 1e-6, 1e3, 1.0),
    ("time,contact force [kN],piston acc (g)", 1.0, 1e3, G),
    ("TIME (ms),FORCE [lbf],ACC [gn]", 1e-3, 4.4482216152605, G),
])
def test_units_in_headers_are_converted(tmp_path, header, time_unit, force_scale, acc_scale):
    t = np.arange(6) * 20e-6 / time_unit
    force = np.array([0.0, 1.0, 3.0, 2.0, 0.5, 0.0])
    acc = -0.5 * force
    path = tmp_path / "run.csv"
    rows = (f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in zip(t, force, acc, strict=False))
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    rec = read_recording(path)
    assert rec.sample_rate == pytest.approx(50e3, rel=1e-9)
    np.testing.assert_allclose(rec.contact_force, force * force_scale, rtol=1e-12)
    np.testing.assert_allclose(rec.piston_acceleration, acc * acc_scale, rtol=1e-12)


def test_sign_flips_gravity_and_explicit_channels(tmp_path):
    path = tmp_path / "lab.csv"
    path.write_text("time [s],Load cell [N],Accel up [m/s^2],Force ref [N]\n"
                    "0,-1,-9.80665,5\n1e-4,-2,-8.80665,6\n2e-4,-3,-7.80665,7\n")
    rec = read_recording(path, force_channel="Load cell", acceleration_channel="Accel up [m/s^2]",
                         flip_force=True, acceleration_includes_gravity=True)
    np.testing.assert_allclose(rec.contact_force, [1, 2, 3])
    np.testing.assert_allclose(rec.piston_acceleration, [0, 1, 2], atol=1e-12)
    np.testing.assert_allclose(rec.channel("Force ref"), [5, 6, 7])
    assert rec.metadata["read_options"] == {"flip_force": True, "acceleration_includes_gravity": True}
    flipped = read_recording(path, force_channel="Load cell", acceleration_channel="Accel up",
                             flip_acceleration=True)
    np.testing.assert_allclose(flipped.piston_acceleration, [9.80665, 8.80665, 7.80665])
    with pytest.raises(RecordingError, match=r"force_channel 'strain' not found; channels found: \['Load cell \[N\]'"):
        read_recording(path, force_channel="strain")


def test_missing_force_channel_lists_the_channels_found(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("time [s],voltage [V]\n0,1\n1e-4,2\n")
    with pytest.raises(RecordingError, match=r"no contact_force channel .*channels found: \['voltage \[V\]'\]"):
        read_recording(path)


def _csv(tmp_path, text, name="bad.csv"):
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


@pytest.mark.parametrize("text, match", [
    ("", "file is empty"),
    ("# only a comment\n\n", "file is empty"),
    ("time [s],force [N]\n", "no data rows"),
    ("0,1\n1,2\n", "first row must be a header"),
    ("time,force,force\n0,1,2\n", "distinct"),
    ("time [s],force [N]\n0,1\n1e-4,abc\n", r"data row 2, column 'force \[N\]' holds 'abc'; expected a number"),
    ("time [s],force [N]\n0,1\n1e-4\n", "data row 2 has 1 cells; expected 2"),
    ("time [s],force [N]\n0,1\n1e-4,nan\n2e-4,3\n", r"'force \[N\]' has a non-finite sample \(nan\) at index 1"),
    ("time [s],force [N]\n0,1\n1e-4,2\n0.5e-4,3\n", "time must increase strictly; sample 2"),
    ("time [s],force [N]\n0,1\n1e-4,2\n3e-4,3\n4e-4,3\n", "time must be regularly sampled"),
    ("time [s],force [m]\n0,1\n1e-4,2\n", r"channel 'force \[m\]' has unit 'm'; expected a force unit"),
    ("time [s],force [N]\n0,1\n", "time must have at least 2 samples"),
    (b"\x00\x01\x02binary", "not a text file"),
])
def test_bad_csv_raises_recording_error_naming_the_file(tmp_path, text, match):
    path = _csv(tmp_path, text)
    with pytest.raises(RecordingError, match=match) as info:
        read_recording(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("sidecar, match", [
    ("{not json", "sidecar must be valid JSON"),
    ("[1, 2]", "sidecar must hold a JSON object"),
    ('{"sample_rate": "fast"}', "sidecar sample_rate must be a number"),
    ('{"sample_rate": -5}', r"must be a number within \[1, 1e\+08\] Hz"),
    ('{"sample_rate": 1e300}', r"must be a number within \[1, 1e\+08\] Hz"),
    ('{"mass_kg": "heavy", "sample_rate": 1000}', "metadata mass_kg must be a number with an optional mass unit"),
])
def test_bad_sidecar_raises_recording_error(tmp_path, sidecar, match):
    path = _csv(tmp_path, "force [N]\n1\n2\n", "run.csv")
    (tmp_path / "run.json").write_text(sidecar)
    with pytest.raises(RecordingError, match=match) as info:
        read_recording(path)
    assert "run.json" in str(info.value) or "run.csv" in str(info.value)


def test_sidecar_named_file_csv_json_is_also_read(tmp_path):
    path = _csv(tmp_path, "force [N]\n1\n2\n", "run.csv")
    (tmp_path / "run.csv.json").write_text(json.dumps({"sample_rate": 1e4, "mass_kg": 3.0}))
    rec = read_recording(path)
    assert rec.sample_rate == 1e4 and rec.truth("mass_kg") == 3.0


def test_written_file_is_readable_by_numpy(tmp_path):
    rec = Recording(sample_rate=1e3, channels={"contact_force": [1.0, 2.0, 3.0]}, metadata={"note": "x"})
    path = write_recording(rec, tmp_path / "r.csv")
    table = np.genfromtxt(path, delimiter=",", skip_header=1)
    np.testing.assert_allclose(table, [[0, 1], [1e-3, 2], [2e-3, 3]])
