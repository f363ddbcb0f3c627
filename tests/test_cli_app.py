"""The command line as a whole: --version, help text, narrow terminals."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import typer.main
from typer.testing import CliRunner

from impactometer import __version__
from impactometer.cli import app
from test_cli_simulate import run

runner = CliRunner()


def test_version():
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"impactometer {__version__}"


def _commands(group, path=()):
    for name, command in group.commands.items():
        if hasattr(command, "commands"):
            yield from _commands(command, (*path, name))
        else:
            yield (*path, name), command


def test_help_has_no_type_placeholders_and_every_option_explained():
    root = typer.main.get_command(app)
    commands = [((), root), *_commands(root)]
    assert {"identify", "stream", "build"} <= {path[-1] for path, _ in commands[1:]}
    for path, command in commands:
        text = runner.invoke(app, [*path, "--help"], env={"COLUMNS": "80"}).output
        assert "<bool>" not in text and "{" not in text.splitlines()[0], (path, text)
        for param in command.params:
            if param.param_type_name == "option":
                assert param.help, f"impactometer {' '.join(path)} {param.opts[0]} has no help"


def test_identify_and_stream_take_the_reader_options_of_inspect():
    def options(command):
        text = runner.invoke(app, [command, "--help"], env={"COLUMNS": "200"}).output
        return {word for line in text.splitlines() for word in line.split() if word.startswith("--")}

    reader = {"--sample-rate", "--force-channel", "--acceleration-channel", "--group", "--flip-force",
              "--flip-acceleration", "--acceleration-includes-gravity", "--cfc", "--time-unit", "--force-unit",
              "--acceleration-unit"}
    for command in ("inspect", "identify", "stream"):
        assert reader <= options(command), command


def test_help_imports_no_heavy_module():
    code = ("import sys; from impactometer.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in ('numba', 'scipy', 'matplotlib', 'h5py') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


def _help(path, columns=200):
    return runner.invoke(app, [*path, "--help"], env={"COLUMNS": str(columns)}).output


def test_a_group_run_bare_prints_its_help_not_an_error_line(capsys):
    for argv, commands in (([], ("simulate", "identify", "map")), (["map"], ("build", "info"))):
        status, text, err = run(argv, capsys)
        assert status == 0 and err == "" and "error:" not in text
        assert text.startswith("Usage: ") and " [OPTIONS] COMMAND [ARGS]..." in text.splitlines()[0], text
        assert len(text.splitlines()) > 5, text
        assert "Commands:" in text and all(f"\n  {name} " in text for name in commands), text


def test_help_names_quantities_and_values_in_words():
    simulate = _help(["simulate"])
    for shown in ("--mass MASS", "--height LENGTH", "--velocity VELOCITY", "--pressure PRESSURE", "--duration TIME",
                  "--sample-rate FREQUENCY", "--out FILE"):
        assert shown in simulate, shown
    assert "--noise FRACTION" in _help(["record"]) and "--cfc CLASS" in _help(["inspect"])
    root = typer.main.get_command(app)
    for path, _ in _commands(root):
        text = _help(path)
        assert not re.search(r"<\w+>", text), (path, text)


def _option(path, name):
    command = typer.main.get_command(app)
    for part in path:
        command = command.commands[part]
    return next(p for p in command.params if name in p.opts)


def test_contact_help_states_the_default_law():
    from impactometer.rig import get_rig

    assert get_rig().contact.law == "hysteretic"
    for path in (["simulate"], ["record"], ["absorb"], ["study"], ["map", "build"]):
        option = _option(path, "--contact")
        assert option.help == ("Contact law: hysteretic, kelvin-voigt (kv), hunt-crossley (hunt) or power (masing) "
                               "(default: the stand's own, hysteretic on drop-stand)."), path
        assert option.metavar == "LAW"


def test_absorb_help_and_default_stand_agree():
    from impactometer.rig import ABSORPTION_RIG, PRESETS

    assert _option(["absorb"], "--rig").default == ABSORPTION_RIG == "drop-stand"
    text = " ".join(_help(["absorb"]).split())
    assert "[default: drop- stand]" in text or "[default: drop-stand]" in text
    assert "on the built-in pad stand, drop-stand, unless --rig" in text and "drop-stand-pad" not in text
    assert PRESETS[ABSORPTION_RIG].contact.law == "hysteretic"  # the pad stand


def test_overwrite_is_the_flag_and_force_its_hidden_earlier_name():
    root = typer.main.get_command(app)
    writers = {path for path, command in _commands(root) if any("--overwrite" in p.opts for p in command.params)}
    assert writers == {("simulate",), ("absorb",), ("demo",), ("identify",), ("record",), ("inspect",), ("study",),
                       ("map", "build"), ("calibrate",), ("validate",), ("rig", "show")}
    for path in writers:
        options = {word.strip(",") for word in _help(path).split() if word.startswith("--")}
        assert "--overwrite" in options and "--force" not in options, path


def test_absorb_table_names_what_auto_ran_and_what_its_stroke_rows_measure(capsys, monkeypatch):
    """The table names the strategy ``auto`` ran, says what the stroke share and bottoming out measure (the mass
    passes the piston's usable stroke by the pad's compression without bottoming out), and keeps to
    ``PIPED_WIDTH`` characters off a terminal."""
    from impactometer.cli.app import PIPED_WIDTH
    from impactometer.control.strategies import ALL, AUTO

    monkeypatch.delenv("COLUMNS", raising=False)
    status, out, err = run(["absorb", "--strategy", "auto", "--method", "oracle"], capsys)
    assert status == 0, err
    assert f"auto ({AUTO})" in out and AUTO in ALL
    assert "mass travel / usable stroke (pad included)" in out and "bottomed out (piston on the bottom stop)" in out
    assert "the controller's limit on the piston" in out
    assert max(len(line) for line in out.splitlines()) <= PIPED_WIDTH


def test_absorb_takes_the_response_map_as_identify_spells_it(capsys):
    """``--method response-map --map FILE`` as in ``identify``; ``--identify`` and ``--response-map`` still work."""
    for argv in (["--method", "response-map", "--map", "missing.h5"],
                 ["--identify", "response-map", "--response-map", "missing.h5"]):
        status, out, err = run(["absorb", *argv], capsys)
        assert status == 2 and err == "error: --map: 'missing.h5' does not exist\n", err
    status, out, err = run(["absorb", "--map", "missing.h5"], capsys)
    assert status == 2 and "--map is only used with --method response-map, got --method model" in err
    text = _help(["absorb"])
    assert "--method NAME" in text and "--map FILE" in text and "--identify" not in text and "--response-map" \
        not in text


@pytest.mark.parametrize("argv, line", [
    # record, not simulate: simulate first says on stderr when it compiles its kernels (a cold cache)
    (["record", "--out", "r.csv", "--pressure", "900kPa"], "--pressure 900kPa: must be <= the rated 400000 Pa of "
                                                           "'drop-stand'"),
    (["record", "--out", "r.csv", "--mass", "0.05kg"], "--mass 0.05kg: must be >= 0.1 [kg]"),
    (["record", "--out", "r.csv", "--pressure", "200"], "--pressure 200: a bare number is SI (Pa); did you mean "
                                                        "200kPa? (write 200Pa to mean it)"),
    (["absorb", "--mass", "2000"], "--mass 2000: a bare number is SI (kg); did you mean 2000g? (write 2000kg to "
                                   "mean it)"),
    (["absorb", "--strategy", "fastest"], "--strategy fastest: must be one of"),
    (["map", "build", "--out", "m.h5", "--pressure", "900kPa"], "--pressure 900kPa: must be <= the rated"),
    (["map", "build", "--out", "m.h5", "--features", "x"], "--features x: must be one of"),
    (["study", "peak-force", "--out", "s", "--sample-rate", "50"], "--sample-rate 50: a bare number is SI (Hz); "
                                                                   "did you mean 50kHz?"),
])
def test_errors_name_the_option_and_the_text_given(argv, line, capsys):
    status, out, err = run(argv, capsys)
    assert status == 2 and out == "" and err.startswith(f"error: {line}") and err.count("\n") == 1, err


def test_the_python_api_keeps_its_parameter_names():
    from impactometer.errors import ParameterError
    from impactometer.rig import Scenario, get_rig

    with pytest.raises(ParameterError, match=r"^pressure_gauge must be <= the rated 400000 Pa") as exc:
        Scenario(mass=30.0, velocity=2.0, pressure_gauge=9e5).check_against(get_rig())
    assert (exc.value.field, exc.value.expected) == ("pressure_gauge", "must be <= the rated 400000 Pa of "
                                                                       "'drop-stand'")
    with pytest.raises(ParameterError, match=r"^mass must be >= 0.1 \[kg\], got 0.05$") as exc:
        Scenario(mass=0.05, velocity=2.0)
    assert (exc.value.field, exc.value.expected) == ("mass", "must be >= 0.1 [kg]")


def test_speak_maps_core_names_to_options():
    from impactometer.cli.app import given, speak
    from impactometer.errors import ParameterError, RecordingError

    rated = ParameterError("pressure_gauge[0] must be <= 4 Pa, got 5.0")
    assert speak(rated, {"pressure": "9kPa"}) == "--pressure 9kPa: must be <= 4 Pa"
    assert speak(rated, {"pressure": None}) == str(rated)  # not given: nothing to name
    assert speak(rated, {"mass": "3kg"}) == str(rated)  # not one of the options: left as it is
    hint = RecordingError("f.csv: no channel (pass force_channel or pass group); the group holds sample_rate=5")
    assert speak(hint, {"force_channel": None, "group": None, "sample_rate": None}) == \
        "f.csv: no channel (pass --force-channel or pass --group); the group holds --sample-rate=5"
    with pytest.raises(RecordingError, match=r"^--cfc 7: must be one of \[60\]$") as exc, given(cfc=7):
        raise RecordingError("cfc must be one of [60], got 7")
    assert exc.value.field == "cfc"


def test_study_summary_in_a_pipe_keeps_paths_whole(tmp_path, capsys):
    """Written to a file or a pipe (no terminal), no path is broken: the folder on a line of its own, the files in
    the table by name."""
    out = tmp_path / ("a folder whose name makes every path longer than eighty columns" + "/case s")
    out.parent.mkdir()
    status, text, err = run(["study", "peak-force", "--out", str(out), "--grid", "2", "--workers", "1"], capsys)
    assert status == 0, err
    assert f"studies in {out} (" in text and f"report written to {out / 'index.html'}" in text, text
    assert "peak-force.csv" in text and max(len(line) for line in text.splitlines() if "│" in line) <= 120, text


def test_bare_impactometer_prints_its_help_and_exits_0_with_the_installed_click():
    """click 8.2 made a group run bare a usage error (status 2); the command prints its help and succeeds."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")}
    done = subprocess.run([sys.executable, "-m", "impactometer"], capture_output=True, text=True, env=env)
    assert done.returncode == 0 and done.stderr == "", done.stderr
    assert done.stdout.startswith("Usage: ") and "Commands:" in done.stdout
