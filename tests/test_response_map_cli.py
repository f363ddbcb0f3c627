"""``impactometer map build`` and ``impactometer map info``, run in-process."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from impactometer.identify.response_map import identify_recording, load_map
from impactometer.io import write_recording
from impactometer.rig import get_rig
from impactometer.sensors import record_batch
from test_cli_simulate import assert_error_line, run


def test_build_refine_and_info(tmp_path, capsys):
    out = tmp_path / "map.h5"
    status, text, err = run(["map", "build", "--grid", "5x4", "--mass", "10kg:50kg", "--height", "5cm:50cm",
                             "--pressure", "200kPa", "--features", "peaks", "--refine", "30x20", "--out", str(out)],
                            capsys)
    assert status == 0, text + err
    rmap = load_map(out)
    assert rmap.shape == (30, 20) and rmap.feature_set == "peaks"
    assert rmap.provenance["base_grid"] == [5, 4]
    assert rmap.velocities[-1] == pytest.approx(np.sqrt(2 * get_rig().gravity * 0.5))
    status, text, err = run(["map", "info", str(out), "--json"], capsys)
    assert status == 0, err
    summary = json.loads(text)
    assert summary["grid"] == [30, 20] and summary["pressures_gauge_Pa"] == [200e3]
    assert set(summary["features"]) == {"first_peak", "second_peak"}


def test_pressure_axis_window_and_velocity_range(tmp_path, capsys):
    out = tmp_path / "map.h5"
    status, text, err = run(["map", "build", "--grid", "4", "--velocity", "1m/s:3m/s", "--pressure",
                             "100kPa,300kPa", "--window", "10ms", "--out", str(out)], capsys)
    assert status == 0, text + err
    rmap = load_map(out)
    np.testing.assert_allclose(rmap.pressures_gauge, [100e3, 300e3])
    assert rmap.feature_params["window"] == pytest.approx(0.01)
    np.testing.assert_allclose(rmap.velocities[[0, -1]], [1.0, 3.0])


def test_existing_map_is_not_overwritten_without_force(tmp_path, capsys):
    out = tmp_path / "map.h5"
    out.write_bytes(b"precious")
    status, text, err = run(["map", "build", "--grid", "4x4", "--out", str(out)], capsys)
    assert_error_line(status, text, err)
    assert "--overwrite" in err
    assert out.read_bytes() == b"precious"
    status, _, err = run(["map", "build", "--grid", "4x4", "--out", str(out), "--force"], capsys)
    assert status == 0, err
    assert load_map(out).shape == (4, 4)


@pytest.mark.parametrize("args, message", [
    (["--grid", "1x10"], "--grid: expected MASSESxVELOCITIES"),
    (["--mass", "50kg:10kg"], "--mass: expected 0 <= LOW < HIGH"),
    (["--pressure", "300kPa,100kPa"], "--pressure: expected one pressure or an increasing comma list"),
    (["--pressure", "900kPa"], "--pressure 900kPa: must be <= the rated 400000 Pa"),
    (["--features", "fft"], "--features fft: must be one of"),
    (["--features", "peaks", "--window", "20ms"], "--window applies to"),
    (["--height", "5cm:50cm", "--velocity", "1m/s:3m/s"], "at most one of --height and --velocity"),
])
def test_bad_options_fail_in_one_line(tmp_path, capsys, args, message):
    status, out, err = run(["map", "build", "--out", str(tmp_path / "m.h5"), *args], capsys)
    assert_error_line(status, out, err)  # refused before any progress is printed
    assert message in " ".join(err.splitlines()[-1].split())
    assert "Traceback" not in out + err
    assert not (tmp_path / "m.h5").exists()


def test_info_of_a_bad_file_fails_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.h5"
    bad.write_text("not a map")
    status, out, err = run(["map", "info", str(bad)], capsys)
    assert_error_line(status, out, err)
    assert out == "" and "not an HDF5 file" in err


def test_build_from_a_calibration_folder_with_manifest(tmp_path, capsys):
    rig = get_rig()
    masses = np.linspace(10, 50, 4)
    velocities = np.sqrt(2 * rig.gravity * np.linspace(0.05, 0.5, 4))
    m, v = (a.ravel() for a in np.meshgrid(masses, velocities, indexing="ij"))
    folder = tmp_path / "calibration"
    folder.mkdir()
    with open(folder / "manifest.csv", "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["file", "mass_kg", "velocity_m_s", "pressure_gauge_Pa"])
        for i, recording in enumerate(record_batch(m, v, 200e3, rig, duration=0.03, seed=1)):
            name = f"drop{i:02d}.h5"
            # the truth lives in the manifest only
            write_recording(type(recording)(sample_rate=recording.sample_rate, channels=recording.channels,
                                            metadata={"rig": "drop-stand"}), folder / name)
            writer.writerow([name, m[i], v[i], 200e3])
    out = tmp_path / "map.h5"
    status, text, err = run(["map", "build", "--from-recordings", str(folder), "--grid", "12x12", "--out",
                             str(out)], capsys)
    assert status == 0, text + err
    rmap = load_map(out)
    assert rmap.provenance["source"] == "recordings" and rmap.provenance["recordings"] == 16
    probe = record_batch(30.0, 2.0, 200e3, rig, duration=0.03)[0]
    result = identify_recording(probe, rmap)
    assert result.velocity == pytest.approx(2.0, rel=0.02)  # 4×4 calibration points: coarse, but consistent


def test_identify_with_a_map_needs_the_charge_pressure(tmp_path, capsys):
    out = tmp_path / "map.h5"
    status, text, err = run(["map", "build", "--grid", "6", "--out", str(out)], capsys)
    assert status == 0, text + err
    recording = record_batch(30.0, 1.5, 100e3, duration=0.06, noise=0.01, seed=2)[0]
    bare = write_recording(type(recording)(sample_rate=recording.sample_rate, channels=recording.channels,
                                           start_time=recording.start_time), tmp_path / "bare.h5")
    command = ["identify", str(bare), "--method", "response-map", "--map", str(out), "--json"]
    status, text, err = run(command, capsys)
    assert_error_line(status, text, err)
    assert "the charge pressure is not known" in err and "--pressure" in err
    status, text, err = run([*command, "--pressure", "100kPa"], capsys)
    assert_error_line(status, text, err)
    assert "made for a charge pressure of 200 kPa, the measurement is at 100 kPa" in err
    stated = write_recording(recording, tmp_path / "stated.h5")
    status, text, err = run(["identify", str(stated), "--method", "response-map", "--map", str(out), "--pressure",
                             "200kPa"], capsys)
    assert_error_line(status, text, err)
    assert "contradicts the recording's pressure_gauge_Pa of 100 kPa" in err
    status, text, err = run(["identify", str(stated), "--pressure", "100kPa"], capsys)
    assert_error_line(status, text, err)
    assert "--pressure is an option of --method response-map and --method model" in err
