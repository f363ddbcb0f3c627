"""The typer application and the helpers every command module shares (units, errors, output files)."""

from __future__ import annotations

import copy
import math
import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, overload

import typer
import typer.core
from rich.console import Console, ConsoleDimensions
from rich.progress import Progress

from .. import __version__
from ..errors import ImpactometerError
from ..outputs import HDF5_EXTENSIONS, check_file, figure_formats
from ..units import parse_quantity

#: earlier spellings of options, still accepted and left out of the help: old spelling -> the one shown
OLD_SPELLINGS = {"--force": "--overwrite", "--identify": "--method", "--response-map": "--map"}
#: the declaration of the flag that lets a command replace existing output files (``--force`` before)
OVERWRITE = ("--overwrite", "--force")
#: the help's placeholder of an option's value where it declares none, by the value's Python type
METAVARS = {str: "TEXT", int: "INTEGER", float: "NUMBER", Path: "PATH"}


class Command(typer.core.TyperCommand):
    """A command whose usage line names its arguments as click does (``FILE``, not ``{FILE}``), whose help shows
    a placeholder in words for every value (``TEXT``, not ``<str>``; an argument its name alone) and leaves out
    :data:`OLD_SPELLINGS`."""

    def __init__(self, *args, **options):
        super().__init__(*args, **options)
        for param in self.params:
            kind = getattr(getattr(param, "type_descriptor", None), "annotation", None)
            if param.param_type_name == "option" and param.metavar is None and not getattr(param, "is_flag", False):
                param.metavar = METAVARS.get(kind, "TEXT")

    def collect_usage_pieces(self, ctx):
        return [re.sub(r"^\{(.*)\}(\.\.\.)?$", r"\1\2", piece) for piece in super().collect_usage_pieces(ctx)]

    def format_options(self, ctx, formatter):
        sections = {"Arguments": [], "Options": []}
        for param in self.get_params(ctx):
            shown = copy.copy(param)
            shown.opts = [o for o in param.opts if o not in OLD_SPELLINGS] or param.opts
            if param.param_type_name == "argument":  # its name (FILE) says what it takes: no <path> beside it
                shown.display_type_rich = lambda ctx: None
            record = shown.get_help_record(ctx)
            if record is not None and param.param_type_name in ("argument", "option"):
                sections["Arguments" if param.param_type_name == "argument" else "Options"].append(record)
        for title, records in sections.items():
            if records:
                with formatter.section(title):
                    formatter.write_dl(records)


class App(typer.Typer):
    """The typer application of impactometer: plain help text (no type placeholders), :class:`Command` commands."""

    def __init__(self, **options):
        super().__init__(**{"no_args_is_help": True, "rich_markup_mode": None, **options})

    def command(self, *args, **options):
        return super().command(*args, **{"cls": Command, **options})


app = App(add_completion=False, pretty_exceptions_enable=False,
          help="On-line impact load identification and adaptive impact absorption.")

#: width of the tables where the output is not a terminal and COLUMNS does not say [characters]
PIPED_WIDTH = 120


class _Console(Console):
    """A rich Console that, writing to a file or a pipe (and COLUMNS unset), lays tables out :data:`PIPED_WIDTH`
    characters wide (rich's default there is 80); plain lines are printed whole (``soft_wrap``), so a path or a
    one-line message is never broken."""

    @property
    def size(self) -> ConsoleDimensions:
        size = Console.size.fget(self)  # type: ignore[attr-defined]
        if self.is_terminal or self._width is not None or "COLUMNS" in os.environ:
            return size
        return ConsoleDimensions(PIPED_WIDTH, size.height)

    @size.setter
    def size(self, new_size: tuple[int, int]) -> None:
        Console.size.fset(self, new_size)  # type: ignore[attr-defined]


console = _Console(soft_wrap=True)  # paths and one-line messages are never broken (the terminal wraps)
#: errors go to standard error, so that standard output holds only results (``--json`` pipes stay parsable)
error_console = _Console(soft_wrap=True, stderr=True)


class QuietProgress(Progress):
    """A rich Progress that, disabled, writes nothing at all: rich 13.0 (the declared floor) prints an empty line
    when a disabled bar stops, which would break the one-line output of errors and notices off a terminal."""

    def stop(self) -> None:
        if not self.disable:
            super().stop()


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
    """Parse a CLI quantity with an optional unit suffix (SI when bare, and refused when a bare number lies outside
    the quantity's plausible range: :data:`~impactometer.units.BARE_RANGES`); None passes through."""
    return None if text is None else parse_quantity(text, dimension, field=field, plausible=True)


#: what the core calls a parameter -> the option that gives it (as Python spells the option), where they differ
CORE_NAMES = {"pressure_gauge": "pressure", "pressure_gauge_std": "pressure_std",
              "contact.law": "contact", "identification": "method",
              "response_map": "map", "extra_channels": "extra"}


def option_name(key: str) -> str:
    """The option of a parameter as Python spells it: ``sample_rate`` -> ``--sample-rate``."""
    return "--" + key.replace("_", "-")


@contextmanager
def given(**texts: object) -> Iterator[None]:
    """Errors of the core about the options named here speak the command line: they name the option and the user's
    text instead of the Python parameter.

    Keywords are options as Python spells them (``sample_rate`` for ``--sample-rate``; :data:`CORE_NAMES` says
    which parameter of the core each gives where the names differ), values the user's text (None: not given). An
    error about one of them (its ``field``) and the expectation it states become ``--pressure 900kPa: must be <= the
    rated 400000 Pa of 'drop-stand'``; elsewhere in a message a parameter's Python name written as code
    (``force_channel``, ``pass group``) becomes the option. The Python API keeps its own messages.
    """
    try:
        yield
    except ImpactometerError as exc:
        spoken = speak(exc, texts)
        if spoken == str(exc):
            raise
        raise type(exc)(spoken, field=exc.field, expected=exc.expected).with_traceback(exc.__traceback__) from None


def speak(error: ImpactometerError, texts: dict[str, object]) -> str:
    """The message of ``error`` on the command line, for the options ``texts`` (see :func:`given`)."""
    keys = {core: key for core, key in CORE_NAMES.items() if key in texts} | {key: key for key in texts}
    key = keys.get(error.field or "")
    if key is not None and (texts[key] is None or not error.expected):  # about an option not given: as it is
        return str(error)
    if key is not None:
        return f"{option_name(key)} {texts[key]}: {error.expected}"
    return speak_text(str(error), texts)


def speak_text(message: str, texts: dict[str, object]) -> str:
    """``message`` (an error's or a warning's) with the Python names of the options ``texts`` written as the
    options (see :func:`given`)."""
    keys = {core: key for core, key in CORE_NAMES.items() if key in texts} | {key: key for key in texts}
    for core, key in keys.items():
        if option_name(key) in message:  # the message names the option already
            continue
        # a name of several words is code wherever it stands; a plain word only where the message says to pass it
        name = re.escape(core)
        written = rf"(?<![\w.-]){name}\b" if "_" in core or "." in core else rf"(?<=\bpass ){name}\b"
        message = re.sub(written, option_name(key), message)
    return message


def output_path(path: Path | None, overwrite: bool, *, field: str = "--out", kind: str | None = None) -> Path | None:
    """Check an output file before any work: a file name (with an extension of its ``kind``: ``figure``,
    ``recording`` or ``hdf5``), in a writable folder, not replacing an existing file unless ``--overwrite``."""
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
    return check_file(path, field, overwrite=overwrite, extensions=extensions, flag="--overwrite")


@contextmanager
def announce_compilation(doing: str, *, compile_time: str = "about 10-30 s", spinner: bool = True) -> Iterator[None]:
    """Say on standard error what the command is ``doing`` while the block runs and, if numba compiles kernels in
    it (a first run: nothing in numba's cache), that it does and how long that takes (``compile_time``, measured
    on a cold cache): a spinner with the elapsed time on a terminal; elsewhere (a log, a pipe), or without
    ``spinner`` (a block that prints as it goes or shows its own progress bar), one plain line, and only when it
    compiles (``doing: compiling kernels, first run only (about 10-30 s) ...``)."""
    from rich.progress import SpinnerColumn, TextColumn, TimeElapsedColumn
    from rich.table import Column

    from ..studies.executors import compiling

    live = spinner and error_console.is_terminal
    note = f"compiling kernels, first run only ({compile_time})"
    bar = QuietProgress(SpinnerColumn(), TimeElapsedColumn(),
                        TextColumn("{task.description}", table_column=Column(overflow="fold")), console=error_console,
                        transient=True, disable=not live, redirect_stdout=False, redirect_stderr=False)
    task = bar.add_task(doing, total=None)

    def compiling_now() -> None:
        if live:
            bar.update(task, description=f"{doing}: {note}")
        else:
            error_console.print(f"{doing}: {note} ...", highlight=False, markup=False, soft_wrap=True)

    with bar, compiling(compiling_now):
        yield


def with_uncertainty(value: float, std: float | None, unit: str = "", *, digits: int = 4) -> str:
    """``value ± std unit`` with the value rounded where the standard error's first digit sits (1.970 ± 0.004 m/s);
    without a finite, positive ``std``, ``digits`` significant digits."""
    suffix = f" {unit}" if unit else ""
    if std is None or not math.isfinite(std) or std <= 0:
        return f"{value:.{digits}g}{suffix}"
    decimals = max(0, -math.floor(math.log10(std)))
    return f"{value:.{decimals}f} ± {std:.{decimals}f}{suffix}"
