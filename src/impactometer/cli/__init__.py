"""Command-line interface: ``impactometer COMMAND``. Errors print in one line (on standard error) and exit with
status 2; a command group run without a command prints its help."""

from __future__ import annotations

import re
import sys

import typer
from rich.markup import escape

from ..errors import ImpactometerError
from ..outputs import write_failed
from . import calibrate, control, demo, identify, recordings, response_map, rig, simulate, studies  # noqa: F401  (register commands)
from .app import app, error_console

__all__ = ["app", "main"]
_NUMPY_SCALAR = re.compile(r"\bnp\.(?:float|int|uint|complex|bool)\w*\(([^()]*)\)")


def _fail(message: str, code: int) -> None:
    line = " ".join(message.split())  # one line, whatever the message holds
    line = _NUMPY_SCALAR.sub(r"\1", line)  # np.float64(3.0) -> 3.0, wherever a message kept a numpy repr
    error_console.print(f"[bold red]error:[/] {escape(line)}", highlight=False, soft_wrap=True)
    sys.exit(code)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``impactometer`` console script.

    Errors of impactometer and usage errors of the command line print one line and exit with status 2.
    """
    try:
        result = app(args=argv, standalone_mode=False)
    except ImpactometerError as exc:
        _fail(str(exc), 2)
    except KeyboardInterrupt:
        _fail("interrupted", 130)
    except OSError as exc:  # reading or writing a file failed where no check could foresee it (disk full, ...)
        target = exc.filename if exc.filename is not None else "a file"
        _fail(str(write_failed(target, exc)).replace("cannot write", "cannot read or write", 1), 2)
    except Exception as exc:
        # click's exceptions (typer may bundle its own copy of click, so match by interface, not by class)
        name = type(exc).__name__
        if name == "NoArgsIsHelpError":  # a group run bare asks for its help: shown on stdout, status 0 (as click
            # before 8.2 did; click 8.2 made it a usage error with status 2)
            typer.echo(exc.ctx.get_help())  # type: ignore[attr-defined]
            sys.exit(0)
        if hasattr(exc, "format_message"):
            _fail(exc.format_message(), getattr(exc, "exit_code", 2) or 2)
        if name == "Abort":
            _fail("aborted", 130)
        if name == "Exit":
            sys.exit(getattr(exc, "exit_code", 0))
        raise
    if isinstance(result, int) and result:
        sys.exit(result)
