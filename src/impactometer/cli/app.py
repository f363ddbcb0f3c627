"""The typer application and the helpers every command module shares (units, errors, output files)."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console

from ..errors import ParameterError
from ..units import parse_quantity

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="On-line impact load identification and adaptive impact absorption.")
console = Console()


def quantity(text: str | None, dimension: str, field: str) -> float | None:
    """Parse a CLI quantity with an optional unit suffix (SI when bare); None passes through."""
    return None if text is None else parse_quantity(text, dimension, field=field)


def output_path(path: Path | None, force: bool, *, field: str = "--out") -> Path | None:
    """Refuse to overwrite an existing file unless ``--force``."""
    if path is not None and path.exists() and not force:
        raise ParameterError(f"{field}: {str(path)!r} exists; pass --force to overwrite it")
    if path is not None and not path.parent.exists():
        raise ParameterError(f"{field}: folder {str(path.parent)!r} does not exist")
    return path
