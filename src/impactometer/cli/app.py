"""The typer application and the helpers every command module shares (units, errors, output files)."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated, overload

import typer
import typer.core
from rich.console import Console

from .. import __version__
from ..outputs import HDF5_EXTENSIONS, check_file, figure_formats
from ..units import parse_quantity


class Command(typer.core.TyperCommand):
    """A command whose usage line names its arguments as click does (``FILE``, not ``{FILE}``)."""

    def collect_usage_pieces(self, ctx):
        return [piece[1:-1] if piece.startswith("{") and piece.endswith("}") else piece
                for piece in super().collect_usage_pieces(ctx)]


class App(typer.Typer):
    """The typer application of impactometer: plain help text (no type placeholders), :class:`Command` commands."""

    def __init__(self, **options):
        super().__init__(**{"no_args_is_help": True, "rich_markup_mode": None, **options})

    def command(self, *args, **options):
        return super().command(*args, **{"cls": Command, **options})


app = App(add_completion=False, pretty_exceptions_enable=False,
          help="On-line impact load identification and adaptive impact absorption.")
console = Console(soft_wrap=True)  # paths and one-line messages are never broken (the terminal wraps)
#: errors go to standard error, so that standard output holds only results (``--json`` pipes stay parsable)
error_console = Console(soft_wrap=True, stderr=True)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"impactometer {__version__}")
        raise typer.Exit()


@app.callback()
def _options(version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                                   help="Print the version and exit.")] = False) -> None:
    """On-line impact load identification and adaptive impact absorption."""


@overload
def quantity(text: str, dimension: str, field: str) -> float: ...


@overload
def quantity(text: None, dimension: str, field: str) -> None: ...


@overload
def quantity(text: str | None, dimension: str, field: str) -> float | None: ...


def quantity(text: str | None, dimension: str, field: str) -> float | None:
    """Parse a CLI quantity with an optional unit suffix (SI when bare); None passes through."""
    return None if text is None else parse_quantity(text, dimension, field=field)


def output_path(path: Path | None, force: bool, *, field: str = "--out", kind: str | None = None) -> Path | None:
    """Check an output file before any work: a file name (with an extension of its ``kind``: ``figure``,
    ``recording`` or ``hdf5``), in a writable folder, not replacing an existing file unless ``--force``."""
    if path is None:
        return None
    if kind == "figure":
        extensions = figure_formats()
    elif kind == "recording":
        from ..io import FORMATS

        extensions = list(FORMATS)
    elif kind == "hdf5":
        extensions = list(HDF5_EXTENSIONS)
    else:
        extensions = None
    return check_file(path, field, overwrite=force, extensions=extensions)


def announce_compilation() -> None:
    """Say so on stderr before the compiled kernels are built for the first time (no cache beside the model)."""
    cache = Path(__file__).resolve().parents[1] / "model" / "__pycache__"
    if not any(cache.glob("*.nbi")):
        print("compiling kernels, once, about 15 s ...", file=sys.stderr, flush=True)


def with_uncertainty(value: float, std: float | None, unit: str = "", *, digits: int = 4) -> str:
    """``value ± std unit`` with the value rounded where the standard error's first digit sits (1.970 ± 0.004 m/s);
    without a finite, positive ``std``, ``digits`` significant digits."""
    suffix = f" {unit}" if unit else ""
    if std is None or not math.isfinite(std) or std <= 0:
        return f"{value:.{digits}g}{suffix}"
    decimals = max(0, -math.floor(math.log10(std)))
    return f"{value:.{decimals}f} ± {std:.{decimals}f}{suffix}"
