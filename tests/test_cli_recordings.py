"""``impactometer record`` and ``impactometer inspect`` called in-process: files, output and exit codes."""

import json

import numpy as np
import pytest

from impactometer.cli import main
from impactometer.constants import STANDARD_GRAVITY
from impactometer.io import read_recording, write_recording
from impactometer.recording import Recording


@pytest.mark.parametrize("ext", [".csv", ".h5", ".tdms", ".mat"])
def test_record_writes_the_format_of_the_extension(tmp_path, ext, capsys):
    out = tmp_path / f"run{ext}"
    main(["record", "--mass", "30kg", "--height", "0.2m", "--pressure", "200kPa", "--sample-rate", "50kHz",
          "--noise", "2%", "--seed", "4", "--duration", "20ms", "--out", str(out)])
    assert "written to" in capsys.readouterr().out
    rec = read_recording(out)
    assert rec.sample_rate == 50e3 and len(rec) == 2001  # 20 ms default pre-trigger + 20 ms after contact
    assert rec.start_time == pytest.approx(-0.02)
    assert rec.truth("mass_kg") == 30.0
    assert rec.truth("velocity_m_s") == pytest.approx(np.sqrt(2 * STANDARD_GRAVITY * 0.2), rel=1e-12)
    assert rec.metadata["noise"] == {"contact_force": 0.02, "piston_acceleration": 0.02}
    assert rec.metadata["seed"] == 4 and rec.metadata["anti_alias"] == "causal"


def test_record_options_reach_the_sensor_model(tmp_path):
    out = tmp_path / "r.h5"
    main(["record", "--velocity", "1.5m/s", "--mass", "20kg", "--duration", "10ms", "--sample-rate", "20kHz",
          "--pre-trigger", "1ms", "--force-noise", "1%", "--noise", "0", "--adc-bits", "12", "--include-gravity",
          "--extra", "pressure_lower", "--contact", "hunt", "--anti-alias", "zero-phase", "--out", str(out)])
    rec = read_recording(out)
    assert rec.start_time == pytest.approx(-1e-3) and "pressure_lower" in rec.channels
    assert rec.metadata["noise"] == {"contact_force": 0.01} and rec.metadata["contact_law"] == "hunt-crossley"
    assert rec.piston_acceleration[0] == pytest.approx(-STANDARD_GRAVITY, abs=0.01 * STANDARD_GRAVITY + 1.0)
    assert rec.metadata["adc_bits"] == 12 and rec.metadata["anti_alias"] == "zero-phase"


def test_record_refuses_to_overwrite_without_overwrite(tmp_path, capsys):
    out = tmp_path / "r.mat"
    main(["record", "--duration", "5ms", "--out", str(out)])
    before = out.read_bytes()
    with pytest.raises(SystemExit) as exc:
        main(["record", "--duration", "5ms", "--mass", "40kg", "--out", str(out)])
    captured = capsys.readouterr()
    assert exc.value.code == 2 and "exists; pass --overwrite" in captured.err
    assert captured.err.startswith("error:") and captured.err.count("\n") == 1 and "error:" not in captured.out
    assert out.read_bytes() == before
    main(["record", "--duration", "5ms", "--mass", "40kg", "--out", str(out), "--overwrite"])
    assert read_recording(out).truth("mass_kg") == 40.0
    main(["record", "--duration", "5ms", "--mass", "50kg", "--out", str(out), "--force"])  # the earlier name
    assert read_recording(out).truth("mass_kg") == 50.0


@pytest.mark.parametrize("argv, message", [
    (["record", "--out", "x.xlsx"], "unknown extension '.xlsx'"),
    (["record", "--noise", "loud", "--out", "x.csv"], "--noise"),
    (["record", "--noise", "-2%", "--out", "x.csv"], "--noise -2%: must be within [0, 1000%]"),
    (["record", "--noise", "0.8", "--out", "x.csv"], "--noise 0.8: a bare number is a fraction (0.8 = 80%); did "
                                                     "you mean 0.8%? (write 80% to mean it)"),
    (["record", "--force-noise", "2", "--out", "x.csv"], "--force-noise 2: a bare number is a fraction"),
    (["record", "--sample-rate", "1kHz", "--out", "x.csv"], "--sample-rate 1kHz: must be >= 5000"),
    (["record", "--anti-alias", "sinc", "--out", "x.csv"], "--anti-alias sinc: must be"),
    (["record", "--pre-trigger", "-1ms", "--out", "x.csv"], "--pre-trigger -1ms: must be >= 0 [s]"),
    (["record", "--extra", "voltage", "--out", "x.csv"], "unknown channel 'voltage'"),
    (["inspect", "missing.csv"], "no such file"),
    (["inspect", "bad.csv"], "data row 1, column 'force [N]' holds 'x'"),
    (["inspect", "good.csv", "--cfc", "500"], "--cfc 500: must be one of [60, 180, 600, 1000]"),
    (["inspect", "good.csv", "--force-channel", "load"], "good.csv: --force-channel 'load' not found"),
    (["inspect", "nameless.csv"], "or pass --force-channel)"),
    (["inspect", "untimed.csv"], "pass --sample-rate"),
    (["inspect", "good.csv", "--sample-rate", "20"], "--sample-rate 20: a bare number is SI (Hz); did you mean "
                                                     "20kHz?"),
    (["inspect", "good.csv", "--group", "g"], "applies to HDF5 and TDMS files only"),
])
def test_errors_print_one_line_and_exit_2(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.csv").write_text("time [s],force [N]\n0,x\n")
    (tmp_path / "nameless.csv").write_text("time [s],a [N]\n0,1\n0.001,2\n")
    (tmp_path / "untimed.csv").write_text("force [N],acceleration [m/s^2]\n1,2\n3,4\n")
    write_recording(Recording(sample_rate=20e3, channels={"contact_force": np.zeros(50)}), tmp_path / "good.csv")
    with pytest.raises(SystemExit) as exc:
        main(argv)
    captured = capsys.readouterr()
    err = captured.err
    assert exc.value.code == 2 and message in err and "Traceback" not in err
    assert err.startswith("error:") and err.count("\n") == 1  # one line, on stderr
    assert captured.out == ""  # nothing on stdout
    assert not (tmp_path / "x.csv").exists()


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "drop.tdms"
    main(["record", "--duration", "100ms", "--pre-trigger", "5ms", "--noise", "2%", "--seed", "1",
          "--out", str(path)])
    return path


def test_inspect_prints_rate_channels_pulses_and_noise(recorded, capsys):
    main(["inspect", str(recorded)])
    out = capsys.readouterr().out
    for text in ("50000 Hz", "contact_force", "piston_acceleration", "m/s^2", "peak force", "stage B",
                 "contact pulses", "noise std", "truth mass_kg"):
        assert text in out, text


def test_inspect_json_matches_the_recording(recorded, capsys):
    main(["inspect", str(recorded), "--json"])
    data = json.loads(capsys.readouterr().out)
    rec = read_recording(recorded)
    assert data["sample_rate_Hz"] == 50e3 and data["samples"] == len(rec)
    assert data["peak_force_N"] == pytest.approx(rec.contact_force.max() - data["force_offset_N"], rel=1e-9)
    # the built-in stand: one rebound, then sustained contact (stage B) that lasts past the record's end
    assert len(data["pulses"]) == 2 and data["pulses"][1]["sustained"]
    assert data["stage_b_start_s"] == data["pulses"][1]["start_s"]
    assert [p["start_s"] for p in data["pulses"]] == sorted(p["start_s"] for p in data["pulses"])
    assert data["truth"]["mass_kg"] == 30.0


def test_inspect_plot_cfc_and_overwrite(recorded, tmp_path, capsys):
    png = tmp_path / "i.png"
    main(["inspect", str(recorded), "--plot", str(png), "--cfc", "1000"])
    assert png.stat().st_size > 5000 and "figure written" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["inspect", str(recorded), "--plot", str(png)])
    main(["inspect", str(recorded), "--plot", str(png), "--overwrite"])


def test_inspect_reads_a_lab_csv_with_options(tmp_path, capsys):
    path = tmp_path / "lab.csv"
    t = np.arange(400) / 10e3
    force = -np.where(t < 0.01, np.sin(np.pi * t / 0.01), 0.0)  # kN, tension-positive sensor
    acc = -9.80665 + 0 * t
    rows = (f"{f:.6f};{a:.6f}" for f, a in zip(force, acc, strict=False))
    path.write_text("Force [kN];Acc [m/s^2]\n" + "\n".join(rows))
    main(["inspect", str(path), "--sample-rate", "10kHz", "--flip-force", "--acceleration-includes-gravity",
          "--json"])
    data = json.loads(capsys.readouterr().out)
    assert data["peak_force_N"] == pytest.approx(1000.0, rel=1e-3)
    assert data["channels"]["piston_acceleration"]["max"] == pytest.approx(0.0, abs=1e-9)
    assert len(data["pulses"]) == 1
