"""Command-line interface: ``impactometer COMMAND``. Errors print in one line and exit with status 2."""

from __future__ import annotations

import sys

import click

from ..errors import ImpactometerError
from . import control, identify, recordings, response_map, simulate, studies  # noqa: F401  (register commands)
from .app import app, console

__all__ = ["app", "main"]


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``impactometer`` console script."""
    try:
        app(args=argv, standalone_mode=False)
    except ImpactometerError as exc:
        console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
        sys.exit(2)
    except click.exceptions.Abort:
        console.print("aborted")
        sys.exit(130)
    except click.exceptions.ClickException as exc:
        console.print(f"[bold red]error:[/] {exc.format_message()}", highlight=False, soft_wrap=True)
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
