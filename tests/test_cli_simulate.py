"""``impactometer simulate`` and ``impactometer demo``, run in-process."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest
from rich.markup import escape

from impactometer.cli import main
from impactometer.constants import STANDARD_GRAVITY
from impactometer.rig import Scenario, get_rig


def run(args, capsys):
    """Run the CLI; return (exit status, stdout, stderr)."""
    try:
        main(args)
        status = 0
    except SystemExit as exc:
        status = exc.code
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def assert_error_line(status, out, err):
    """A refusal: exit status 2, one line on stderr that starts with "error:", no traceback, no error on stdout."""
    assert status == 2, (out, err)
    assert err.count("\n") == 1 and err.startswith("error:"), err
    assert "Traceback" not in err and "error:" not in out, out


def test_simulate_writes_histories_and_figure(tmp_path, capsys):
    out, fig = tmp_path / "run.h5", tmp_path / "run.png"
    status, text, err = run(["simulate", "--mass", "30kg", "--height", "0.2m", "--pressure", "200kPa",
                             "--duration", "20ms", "--sample-rate", "50kHz", "--out", str(out), "--plot", str(fig)],
                            capsys)
    assert status == 0, err
    assert "peak contact force" in text and "energy balance error" in text
    assert fig.stat().st_size > 10_000 and fig.read_bytes()[:4] == b"\x89PNG"
    with h5py.File(out) as f:
        assert f.attrs["mass"] == 30.0
        assert f.attrs["velocity"] == pytest.approx(math.sqrt(2 * STANDARD_GRAVITY * 0.2))
        assert f.attrs["pressure_gauge"] == 200e3
        assert f.attrs["sample_rate"] == pytest.approx(50e3)
        assert json.loads(f.attrs["rig"])["contact"]["law"] == "hysteretic"  # the default stand's pad
        time, force = f["time"][:], f["contact_force"][:]
    assert time.size == 1001 and time[-1] == pytest.approx(0.02)
    assert force.max() > 1000.0  # [N]: a real impact was simulated


def test_simulate_options_velocity_contact_and_rig_file(tmp_path, capsys):
    stand = tmp_path / "stand.toml"
    get_rig().replace(**{"friction.force": 0.0}).to_toml(stand)
    out = tmp_path / "hunt.h5"
    status, _, err = run(["simulate", "--mass", "20", "--velocity", "1.5m/s", "--pressure", "1bar", "--contact",
                          "hunt", "--rig", str(stand), "--duration", "0.01", "--out", str(out)], capsys)
    assert status == 0, err
    with h5py.File(out) as f:
        rig = json.loads(f.attrs["rig"])
        assert (rig["contact"]["law"], rig["friction"]["force"]) == ("hunt-crossley", 0.0)
        assert (f.attrs["mass"], f.attrs["velocity"], f.attrs["pressure_gauge"]) == (20.0, 1.5, 1e5)
        assert np.all(f["friction_force"][:] == 0.0)


@pytest.mark.parametrize("flag", ["--overwrite", "--force"])  # --force: the flag's earlier name, still accepted
def test_simulate_refuses_to_overwrite_without_overwrite(tmp_path, capsys, flag):
    out = tmp_path / "run.h5"
    out.write_bytes(b"precious")
    args = ["simulate", "--velocity", "1m/s", "--duration", "5ms", "--out", str(out)]
    status, text, err = run(args, capsys)
    assert_error_line(status, text, err)
    assert "exists; pass --overwrite" in err
    assert out.read_bytes() == b"precious"
    status, _, err = run(args + [flag], capsys)
    assert status == 0 and h5py.is_hdf5(out), err


@pytest.mark.parametrize("args, message", [
    (["--pressure", "200kPaa"], "--pressure: unknown pressure unit 'kPaa'"),
    (["--mass", "heavy"], "--mass must be a number with an optional mass unit"),
    (["--mass", "-3kg"], "--mass -3kg: must be >= 0.1 [kg]"),
    (["--height", "nan"], "--height must be a finite number"),
    (["--pressure", "500kPa"], "--pressure 500kPa: must be <= the rated 400000 Pa of 'drop-stand'"),
    (["--pressure", "-1kPa"], "--pressure -1kPa: must be >= 0 [Pa]"),
    (["--pressure", "200"], "--pressure 200: a bare number is SI (Pa); did you mean 200kPa? (write 200Pa"),
    (["--height", "20"], "--height 20: a bare number is SI (m); did you mean 20cm or 20mm?"),
    (["--mass", "30000"], "--mass 30000: a bare number is SI (kg); did you mean 30000g?"),
    (["--sample-rate", "50"], "--sample-rate 50: a bare number is SI (Hz); did you mean 50kHz?"),
    (["--duration", "50"], "--duration 50: a bare number is SI (s); did you mean 50ms?"),
    (["--contact", "glue"], "--contact glue: must be one of"),
    (["--integrator", "euler"], "--integrator euler: must be one of ['fast', 'reference']"),
    (["--velocity", "2m/s", "--height", "0.2m"], "give exactly one of --height and --velocity"),
    (["--duration", "50kHz"], "--duration: unknown time unit 'kHz'"),
    (["--rig", "stand.yaml"], "--rig stand.yaml: must be one of"),
])
def test_bad_input_exits_2_with_one_line(args, message, capsys):
    status, out, err = run(["simulate", *args], capsys)
    assert_error_line(status, out, err)
    assert out == ""
    assert message in err


def test_demo_runs_the_whole_chain(tmp_path, capsys):
    out = tmp_path / "demo"
    status, text, err = run(["demo", "--out", str(out)], capsys)
    assert status == 0, err
    assert (out / "impact.png").read_bytes()[:4] == b"\x89PNG"
    assert (out / "absorb.png").read_bytes()[:4] == b"\x89PNG"
    assert "contact pulses" in text and "peak contact force" in text
    assert "robust, final" in text and "paper" in text  # identification of the built-in impact
    assert "realtime" in text and "bottomed out" in text  # the closed loop
    assert "…" not in text and "M1 [kg]" in text  # nothing cut at 80 columns, units kept in the headers


def test_demo_replaces_its_folder_only_with_force(tmp_path, capsys):
    out = tmp_path / "demo"
    out.mkdir()
    (out / "impact.png").write_bytes(b"keep")
    status, text, err = run(["demo", "--out", str(out), "--no-absorb"], capsys)
    assert_error_line(status, text, err)
    assert "--overwrite" in err
    assert (out / "impact.png").read_bytes() == b"keep"
    status, _, err = run(["demo", "--out", str(out), "--no-absorb", "--overwrite"], capsys)
    assert status == 0, err
    assert (out / "impact.png").read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo"]  # nothing piles up beside it


def test_error_line_keeps_bracketed_units(capsys):
    status, out, err = run(["simulate", "--mass", "0kg"], capsys)
    assert_error_line(status, out, err)
    assert "--mass 0kg: must be >= 0.1 [kg]" in err


def test_the_demo_shows_when_each_answer_was_available():
    """The model stream's first answer, milliseconds after contact, beside the batch answers at the record's end."""
    from impactometer.cli.demo import identification_table
    from impactometer.identify.model_fit.select import STAGES

    stand = get_rig()
    table = identification_table(Scenario.from_height(mass=30.0, height=0.2, pressure_gauge=200e3,
                                                      gravity=stand.gravity), stand)
    assert table.columns[-1].header == escape("available at [ms after contact]")  # as rich prints it
    rows = dict(zip(table.columns[0]._cells, table.columns[-1]._cells, strict=True))
    first = next(float(at) for label, at in rows.items() if label.startswith("model stream, first"))
    # the first answer reads the first window (4 ms) after the contact instant the trigger places; before the
    # second window (8 ms) of the batch fit's continuation
    assert 0.0 < first < STAGES[1][0] * 1e3
    model = next(label for label in rows if label.startswith("model ("))
    assert float(rows["robust, final"]) > first and float(rows[model]) > first
    assert list(rows.values()) == sorted(rows.values(), key=float)  # in the order the answers came
