"""The reader options every command that reads a lab file shares (``inspect``, ``identify``, ``stream``).

One set, declared once: :func:`reader_options` adds them to a command's signature and hands the command a
:class:`ReaderOptions` that reads the file.
"""

from __future__ import annotations

import functools
import inspect
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Annotated, get_type_hints

import typer

from .app import given, quantity


@dataclass(frozen=True, kw_only=True)
class ReaderOptions:
    """How to read a recording: channel names, group, sign flips, gravity, time base, CFC filter."""

    force_channel: Annotated[str | None, typer.Option(
        "--force-channel", metavar="NAME", help="Name of the contact force channel (default: found by name).")] = None
    acceleration_channel: Annotated[str | None, typer.Option(
        "--acceleration-channel", metavar="NAME",
        help="Name of the piston acceleration channel (default: found by name).")] = None
    group: Annotated[str | None, typer.Option(
        "--group", metavar="NAME", help="HDF5/TDMS group holding the channels.")] = None
    flip_force: Annotated[bool, typer.Option(
        "--flip-force", help="Change the sign of the force (a load cell mounted the other way).")] = False
    flip_acceleration: Annotated[bool, typer.Option(
        "--flip-acceleration", help="Change the sign of the acceleration (an accelerometer pointing up).")] = False
    acceleration_includes_gravity: Annotated[bool, typer.Option(
        "--acceleration-includes-gravity", help="The accelerometer reads a − g: add g back.")] = False
    sample_rate: Annotated[str | None, typer.Option(
        "--sample-rate", metavar="FREQUENCY", help="Sample rate of a file without a time base (e.g. 50kHz).")] = None
    time_unit: Annotated[str | None, typer.Option(
        "--time-unit", metavar="UNIT", help="The time column's unit, in place of the file's (e.g. ms).")] = None
    force_unit: Annotated[str | None, typer.Option(
        "--force-unit", metavar="UNIT", help="The force's unit, in place of the file's (e.g. kN).")] = None
    acceleration_unit: Annotated[str | None, typer.Option(
        "--acceleration-unit", metavar="UNIT", help="The acceleration's unit, in place of the file's (e.g. g).")] = None
    cfc: Annotated[int | None, typer.Option(
        "--cfc", metavar="CLASS", help="Apply a CFC filter class first (60, 180, 600, 1000).")] = None

    def read(self, path: Path):
        """The :class:`~impactometer.recording.Recording` in ``path``, read and filtered as the options say."""
        from ..io import read_recording

        with given(**{f.name: getattr(self, f.name) for f in fields(self)}):
            rec = read_recording(path, force_channel=self.force_channel,
                                 acceleration_channel=self.acceleration_channel, group=self.group,
                                 flip_force=self.flip_force, flip_acceleration=self.flip_acceleration,
                                 acceleration_includes_gravity=self.acceleration_includes_gravity,
                                 sample_rate=quantity(self.sample_rate, "frequency", "--sample-rate"),
                                 time_unit=self.time_unit, force_unit=self.force_unit,
                                 acceleration_unit=self.acceleration_unit)
        if self.flip_force:
            _check_flip(path, rec)
        if rec.units_note:
            from .app import error_console

            error_console.print(f"note: {rec.units_note}", highlight=False, markup=False)
        if self.cfc is not None:
            from ..filters import filter_recording

            with given(cfc=self.cfc):
                rec = filter_recording(rec, self.cfc)
        return rec


def _check_flip(path: Path, rec) -> None:
    """ParameterError where the force read with ``--flip-force`` reads the contact with the other sign: the file's
    force was positive in compression already."""
    from ..errors import ParameterError
    from ..identify.peak_to_peak.segment import inverted_dip

    dip = inverted_dip(rec.contact_force)
    if dip is not None:
        low, noise = dip
        raise ParameterError(f"--flip-force: read with its sign changed, the force of {path.name} falls to "
                             f"{low:.4g} N ({-low / max(noise, 1e-300):.3g} times its noise) and never rises as far: "
                             "the file's force is positive in compression already; leave --flip-force out")


#: the defaults of every reader option (frozen, so one shared instance serves as the default argument)
DEFAULT_READER = ReaderOptions()


def reader_options(command):
    """Decorator: append the :class:`ReaderOptions` options to a typer command that takes ``reader``."""
    signature = inspect.signature(command, eval_str=True)
    own = [p for p in signature.parameters.values() if p.name != "reader"]
    hints = get_type_hints(ReaderOptions, include_extras=True)
    added = [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default, annotation=hints[f.name])
             for f in fields(ReaderOptions)]
    names = [f.name for f in fields(ReaderOptions)]

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        reader = ReaderOptions(**{name: kwargs.pop(name) for name in names if name in kwargs})
        return command(*args, reader=reader, **kwargs)

    wrapper.__signature__ = signature.replace(parameters=own + added)
    wrapper.__annotations__ = {p.name: p.annotation for p in own + added}
    return wrapper
