"""``impactometer identify`` and ``stream`` on a recording file written in the test."""

import json
import time

import numpy as np
import pytest

from impactometer.cli import main
from impactometer.cli.app import with_uncertainty
from impactometer.io import write_recording
from impactometer.model import simulate
from impactometer.recording import Recording
from impactometer.rig import Scenario
from impactometer.sensors import record


@pytest.fixture(scope="module")
def rec_file(tmp_path_factory):
    # the stiff stand: its records have an early answer (on the pad stand the contact-phase fit refuses it)
    r = simulate(Scenario(mass=25, velocity=1.8, pressure_gauge=1.5e5), "drop-stand-stiff", duration=0.08)
    pre = np.zeros(1000)
    rec = Recording(sample_rate=50e3, channels={"contact_force": np.r_[pre, r.contact_force],
                                                "piston_acceleration": np.r_[pre, r.a2]},
                    start_time=-0.02, metadata={"mass_kg": 25.0, "velocity_m_s": 1.8}, source="test")
    path = tmp_path_factory.mktemp("rec") / "drop.h5"
    write_recording(rec, path)
    return path


def test_identify_json(rec_file, capsys):
    main(["identify", str(rec_file), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert data["mass_kg"] == pytest.approx(25.0, rel=5e-3)
    assert data["velocity_m_s"] == pytest.approx(1.8, rel=2e-3)
    assert data["method"] == "peak-to-peak" and data["variant"] == "robust"
    assert data["early"]["available_at_s"] < data["available_at_s"]
    main(["identify", str(rec_file), "--json", "--variant", "paper"])
    assert json.loads(capsys.readouterr().out)["variant"] == "paper"


def test_identify_table_plot_and_stream(rec_file, tmp_path, capsys):
    out = tmp_path / "fig.png"
    main(["identify", str(rec_file), "--plot", str(out)])
    assert out.stat().st_size > 1000 and "mass M1" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main(["identify", str(rec_file), "--plot", str(out)])  # exists, no --overwrite
    assert exc.value.code == 2
    _assert_error_line(capsys.readouterr(), "--overwrite")
    main(["stream", str(rec_file), "--json", "--chunk", "64"])
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    assert lines[0]["kind"] == "early" and lines[-1]["mass_kg"] == pytest.approx(25.0, rel=5e-3)


def test_errors_exit_2(rec_file, tmp_path, capsys):
    for argv, message in ((["identify", str(rec_file), "--method", "magic"], "--method"),
                          (["identify", str(rec_file), "--method", "response-map"], "--map")):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        _assert_error_line(capsys.readouterr(), message)


def test_identify_with_a_response_map(rec_file, tmp_path, capsys):
    """``--method response-map`` hands the recording to the response-map identification."""
    from impactometer.identify.response_map.build import build_map_simulated
    from impactometer.identify.response_map.store import save_map

    path = save_map(build_map_simulated("drop-stand-stiff", 1.5e5, masses=np.linspace(10, 50, 6),
                                        velocities=np.linspace(1, 3, 6)), tmp_path / "map.h5")
    main(["identify", str(rec_file), "--method", "response-map", "--map", str(path), "--pressure", "150kPa",
          "--json"])
    data = json.loads(capsys.readouterr().out)
    assert data["method"] == "response-map"
    assert data["velocity_m_s"] == pytest.approx(1.8, rel=0.02) and data["mass_kg"] == pytest.approx(25, rel=0.1)


def test_lab_csv_without_time_and_a_flipped_load_cell(tmp_path, capsys):
    """A CSV with no time column and a load cell mounted the other way, identified from the command line."""
    # the stiff stand: its records have an early answer (on the pad stand the contact-phase fit refuses it)
    r = simulate(Scenario(mass=25, velocity=1.8, pressure_gauge=1.5e5), "drop-stand-stiff", duration=0.08)
    path = tmp_path / "export.csv"
    rows = np.column_stack([np.r_[np.zeros(1000), -r.contact_force] / 1e3, np.r_[np.zeros(1000), r.a2]])
    np.savetxt(path, rows, delimiter=",", header="Force [kN],Acceleration [m/s^2]", comments="")
    status = _exit(["identify", str(path), "--json"])
    captured = capsys.readouterr()
    assert status == 2 and captured.out == ""  # --json: nothing but JSON on stdout
    _assert_error_line(captured, "error")  # no time base: says so
    main(["identify", str(path), "--json", "--sample-rate", "50kHz", "--flip-force"])
    data = json.loads(capsys.readouterr().out)
    assert data["mass_kg"] == pytest.approx(25.0, rel=5e-3)
    main(["stream", str(path), "--sample-rate", "50kHz", "--flip-force"])
    text = capsys.readouterr().out
    last = [line for line in text.splitlines() if "estimate" in line][-1]
    assert with_uncertainty(data["mass_kg"], data["mass_std_kg"], "kg") in last and "final answer" in text


def test_record_that_starts_at_first_contact(tmp_path, capsys):
    """No pre-trigger: contact from the first sample, as simulate writes; batch and stream agree on the end."""
    path = tmp_path / "drop.tdms"
    main(["record", "--out", str(path), "--pre-trigger", "0", "--noise", "2%", "--seed", "1"])
    capsys.readouterr()
    main(["identify", str(path), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert data["mass_kg"] == pytest.approx(30.0, rel=0.05)
    assert data["velocity_m_s"] == pytest.approx(1.981, rel=0.02)
    main(["stream", str(path), "--json"])
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert lines[-1]["mass_kg"] == pytest.approx(data["mass_kg"], rel=1e-9)
    assert lines[-1]["available_at_s"] == pytest.approx(data["available_at_s"])


def test_bare_noise_is_a_fraction(tmp_path, capsys):
    status = _exit(["record", "--out", str(tmp_path / "a.tdms"), "--noise", "2"])
    assert status == 2
    _assert_error_line(capsys.readouterr(), "2%")
    assert not (tmp_path / "a.tdms").exists()


def _exit(argv) -> int:
    try:
        main(argv)
    except SystemExit as exc:
        return exc.code
    return 0


def _assert_error_line(captured, *words):
    """One line on stderr that starts with "error:" and holds ``words``; no traceback, no error on stdout."""
    err = captured.err
    assert err.count("\n") == 1 and err.startswith("error:") and "Traceback" not in err, err
    assert "error:" not in captured.out, captured.out
    for word in words:
        assert word in err, (word, err)


def test_paper_variant_cautions_on_noise(tmp_path, capsys):
    path = tmp_path / "noisy.tdms"
    main(["record", "--out", str(path), "--noise", "2%", "--seed", "2"])
    main(["record", "--out", str(tmp_path / "clean.tdms")])
    capsys.readouterr()
    main(["identify", str(path), "--json", "--variant", "paper"])
    assert "noise-free" in json.loads(capsys.readouterr().out)["caution"]
    main(["identify", str(tmp_path / "clean.tdms"), "--json", "--variant", "paper"])
    assert "caution" not in json.loads(capsys.readouterr().out)


def test_uncertainty_is_rounded_at_the_first_digit_of_its_error():
    assert with_uncertainty(1.97013, 0.00396, "m/s") == "1.970 ± 0.004 m/s"
    assert with_uncertainty(30.1, 0.2003, "kg") == "30.1 ± 0.2 kg"
    assert with_uncertainty(34.5123, float("nan"), "kg") == "34.51 kg"


def test_json_names_the_equations_and_cfc_is_refused(rec_file, capsys):
    """--json says which equations each answer used; --cfc with the robust variant exits 2 with one line saying
    why (the filter moves the onsets and colours the noise), and the paper variant still answers."""
    main(["identify", str(rec_file), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert data["stage"] == "final" and data["early"]["stage"] == "early"
    assert set(data["equations"]) >= {"onsets", "extrema", "stage_b_extrema", "separations", "stage_b_samples"}
    for command in ("identify", "stream"):
        with pytest.raises(SystemExit) as exc:
            main([command, str(rec_file), "--cfc", "1000"])
        assert exc.value.code == 2
        captured = capsys.readouterr()
        _assert_error_line(captured, "unfiltered", "--cfc")
        assert len(captured.err.strip().splitlines()) == 1 and captured.out == ""
    main(["identify", str(rec_file), "--cfc", "1000", "--variant", "paper", "--json"])
    assert json.loads(capsys.readouterr().out)["variant"] == "paper"


def test_stream_json_names_the_stage_of_each_line(rec_file, capsys):
    """stream --json: the early answer, then updates, then the final answer, each labelled with its stage; the
    final line is identify's answer and carries the early answer, as identify --json does."""
    main(["stream", str(rec_file), "--json", "--chunk", "64"])
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    stages = [line["stage"] for line in lines]
    assert stages[0] == "early" and stages[-1] == "final" and set(stages[1:-1]) == {"update"}, stages
    assert [line["kind"] for line in lines] == ["early"] + ["estimate"] * (len(lines) - 1)
    main(["identify", str(rec_file), "--json"])
    batch = json.loads(capsys.readouterr().out)
    assert lines[-1]["early"] == lines[0] | {"kind": None, "stage": "early"} or \
        lines[-1]["early"]["mass_kg"] == lines[0]["mass_kg"]
    assert lines[-1]["early"] == batch["early"] and lines[-1]["mass_kg"] == batch["mass_kg"]
    assert lines[-1]["early_reason"] is None and batch["early_reason"] is None


@pytest.fixture(scope="module")
def pad_file(tmp_path_factory):
    """A record on the pad stand, whose hysteretic contact the early fit's law family cannot describe."""
    path = tmp_path_factory.mktemp("pad") / "pad.tdms"
    main(["record", "--out", str(path), "--duration", "60ms", "--noise", "1%", "--seed", "1"])
    return path


def test_identify_and_stream_say_why_there_is_no_early_answer(pad_file, capsys):
    capsys.readouterr()
    main(["identify", str(pad_file), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert data["early"] is None and "follow no law" in data["early_reason"] and "hysteretic" in data["early_reason"]
    main(["stream", str(pad_file), "--json"])
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert "early" not in {line["stage"] for line in lines} and lines[-1]["stage"] == "final"
    assert lines[-1]["early_reason"] == data["early_reason"] and lines[-1]["mass_kg"] == data["mass_kg"]
    main(["identify", str(pad_file)])
    assert "early" in capsys.readouterr().out.replace("\n", " ")  # the table says so too
    main(["identify", str(pad_file), "--json", "--variant", "paper"])
    assert "the paper variant gives no early answer" in json.loads(capsys.readouterr().out)["early_reason"]


def test_flip_force_on_a_file_of_the_right_sign_says_to_leave_it_out(rec_file, capsys):
    for command in ("identify", "stream", "inspect"):
        assert _exit([command, str(rec_file), "--flip-force"]) == 2
        _assert_error_line(capsys.readouterr(), "--flip-force", "positive in compression already", "leave")


def test_stream_options_are_refused_before_the_file_is_read(tmp_path, capsys):
    missing = tmp_path / "not-there.h5"  # never read: the options are refused first
    for option, value, expected in (("--cadence", "0ms", "must be > 0 [s]"), ("--first", "1ms", "must be >= 0.002"),
                                    ("--first", "100ms", "must be <= 0.015")):
        assert _exit(["stream", str(missing), "--method", "model", option, value]) == 2
        _assert_error_line(capsys.readouterr(), f"{option} {value}: {expected}")


def test_stream_model_refuses_a_record_too_short_before_any_estimate(tmp_path, capsys):
    path = tmp_path / "short.h5"
    write_recording(record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), sample_rate=50e3,
                           duration=0.005, noise=0.02, seed=3, pre_trigger=0.02), path)
    assert _exit(["stream", str(path), "--method", "model"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # no first estimate printed before the refusal
    _assert_error_line(captured, "ms after first contact", "needs at least 10 ms")


def test_a_stream_that_cannot_keep_its_cadence_says_so_once(tmp_path, capsys, monkeypatch):
    path = tmp_path / "drop.h5"
    write_recording(record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), sample_rate=50e3,
                           duration=0.03, noise=0.02, seed=4, pre_trigger=0.02), path)
    ticks = iter(range(10**6))  # a processor clock on which every push takes a second
    monkeypatch.setattr(time, "thread_time", lambda: float(next(ticks)))
    main(["stream", str(path), "--method", "model", "--cadence", "5ms"])
    notes = [line for line in capsys.readouterr().err.splitlines() if "more than the cadence" in line]
    assert len(notes) == 1 and "of 5 ms" in notes[0] and "--cadence" in notes[0]
    monkeypatch.setattr(time, "thread_time", lambda: 0.0)  # a machine that keeps up: nothing said
    main(["stream", str(path), "--method", "model", "--cadence", "5ms"])
    assert "cadence" not in capsys.readouterr().err


def test_the_model_fit_falls_back_naming_the_stand_the_file_states_and_keeps_the_early_answer(tmp_path, capsys):
    path = tmp_path / "stiff.h5"
    write_recording(record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), "drop-stand-stiff",
                           sample_rate=50e3, duration=0.1, noise=0.02, seed=3, pre_trigger=0.02), path)
    main(["identify", str(path), "--json"])
    plain = json.loads(capsys.readouterr().out)
    main(["identify", str(path), "--method", "model", "--json"])
    freed = json.loads(capsys.readouterr().out)
    # with the stated pressure's prior the fit moves the pressure to soak up the stiffer stand: the answer names --rig
    assert any("--rig" in warning for warning in freed["warnings"])
    main(["identify", str(path), "--method", "model", "--pressure-std", "0", "--json"])
    model = json.loads(capsys.readouterr().out)
    assert model["path"] == "fallback"  # the built-in stand does not describe a record of the stiff one
    assert any("--rig='drop-stand-stiff'" in warning for warning in model["warnings"])
    assert plain["early"] is not None and model["early"] == plain["early"]  # the robust answer, early one included
