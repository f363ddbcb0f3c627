"""The command line as a whole: --version, help text, narrow terminals."""

import subprocess
import sys

import typer.main
from typer.testing import CliRunner

from impactometer import __version__
from impactometer.cli import app

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
              "--flip-acceleration", "--acceleration-includes-gravity", "--cfc"}
    for command in ("inspect", "identify", "stream"):
        assert reader <= options(command), command


def test_help_imports_no_heavy_module():
    code = ("import sys; from impactometer.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in ('numba', 'scipy', 'matplotlib', 'h5py') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
