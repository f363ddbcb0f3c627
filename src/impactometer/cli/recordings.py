"""``impactometer record`` (simulated recording as a lab file) and ``impactometer inspect`` (what a file holds)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, overload

import typer
from rich.markup import escape
from rich.table import Table

from ..errors import ParameterError
from ..outputs import save_figure
from .app import OVERWRITE, announce_compilation, app, console, given, output_path, quantity
from .reading import DEFAULT_READER, ReaderOptions, reader_options
from .simulate import (
    ContactOpt,
    DurationOpt,
    HeightOpt,
    MassOpt,
    PressureOpt,
    RateOpt,
    RigOpt,
    VelocityOpt,
    stand_and_scenario,
)


@overload
def _fraction(text: str, field: str) -> float: ...


@overload
def _fraction(text: str | None, field: str) -> float | None: ...


def _fraction(text: str | None, field: str) -> float | None:
    """A noise level: ``2%`` or a bare fraction (0.02; a bare number above 0.5 is refused as a percent without its
    sign, see :func:`~impactometer.cli.app.quantity`), at most 1000%."""
    if text is None:
        return None
    value = quantity(text, "fraction", field)
    if not 0 <= value <= 10:
        raise ParameterError(f"{field} {text}: must be within [0, 1000%]")
    return value


@app.command()
def record(
    out: Annotated[Path, typer.Option("--out", metavar="FILE", help="Output file; format from the extension (.csv, "
                                                                    ".h5, .tdms, .mat).")],
    mass: MassOpt = "30kg",
    height: HeightOpt = None,
    velocity: VelocityOpt = None,
    pressure: PressureOpt = "200kPa",
    contact: ContactOpt = None,
    rig: RigOpt = None,
    duration: DurationOpt = "50ms",
    sample_rate: RateOpt = "50kHz",
    noise: Annotated[str, typer.Option("--noise", metavar="FRACTION", help="Noise std per channel: a percent of its "
                                                                          "RMS (2%) or a fraction (0.02, at most "
                                                                          "0.5; above, write the percent).")]
    = "0",
    force_noise: Annotated[str | None, typer.Option("--force-noise", metavar="FRACTION",
                                                    help="Noise of the force channel (overrides --noise).")] = None,
    acceleration_noise: Annotated[str | None, typer.Option("--acceleration-noise", metavar="FRACTION", help="Noise "
                                                           "of the acceleration channel (overrides --noise).")]
    = None,
    seed: Annotated[int | None, typer.Option("--seed", help="Seed of the noise.")] = None,
    pre_trigger: Annotated[str, typer.Option("--pre-trigger", metavar="TIME", help="Time recorded before first "
                                                                                   "contact (0: the record starts "
                                                                                   "at contact).")] = "20ms",
    anti_alias: Annotated[str, typer.Option("--anti-alias", metavar="NAME",
                                            help="causal (default), zero-phase or none.")] = "causal",
    adc_bits: Annotated[int | None, typer.Option("--adc-bits", help="ADC resolution; auto range ±1.25·peak.")]
    = None,
    include_gravity: Annotated[bool, typer.Option("--include-gravity", help="Accelerometer reads a − g.")] = False,
    extra: Annotated[list[str] | None, typer.Option("--extra", metavar="CHANNEL", help="Extra channel "
                                                       "(piston_displacement, pressure_lower, ...); repeatable.")]
    = None,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite an existing file.")] = False,
) -> None:
    """Simulate one drop test and write what the stand's sensors and DAQ would record."""
    from ..io import format_of, write_recording
    from ..sensors import record as make_recording

    format_of(out)
    output_path(out, overwrite, kind="recording")
    stand, scenario = stand_and_scenario(mass, height, velocity, pressure, rig=rig, contact=contact,
                                         default_height="0.2m")
    level = _fraction(noise, "--noise")
    channel_levels = {"contact_force": _fraction(force_noise, "--force-noise"),
                      "piston_acceleration": _fraction(acceleration_noise, "--acceleration-noise")}
    levels = {name: level if value is None else value for name, value in channel_levels.items()}
    with given(sample_rate=sample_rate, duration=duration, seed=seed, pre_trigger=pre_trigger, anti_alias=anti_alias,
               adc_bits=adc_bits, include_gravity=include_gravity, extra=None if extra is None else ",".join(extra)), \
            announce_compilation("simulating the drop and recording it"):
        rec = make_recording(scenario, stand, sample_rate=quantity(sample_rate, "frequency", "--sample-rate"),
                             duration=quantity(duration, "time", "--duration"), noise=levels, seed=seed,
                             pre_trigger=quantity(pre_trigger, "time", "--pre-trigger"), anti_alias=anti_alias,
                             adc_bits=adc_bits, include_gravity=include_gravity, extra_channels=tuple(extra or ()))
    write_recording(rec, out, overwrite=overwrite)
    console.print(f"{len(rec)} samples at {rec.sample_rate:g} Hz ({scenario.mass:g} kg at "
                  f"{scenario.velocity:.4g} m/s, p0 = {scenario.pressure_gauge / 1e3:g} kPa, "
                  f"{stand.contact.law}) written to {out}", highlight=False)


def _inspection_tables(rec, result) -> list[Table]:
    head = Table(title=escape(rec.source), show_header=False)
    head.add_row("duration", f"{result.duration * 1e3:.3f} ms ({result.samples} samples)")
    head.add_row("sample rate", f"{result.sample_rate:g} Hz")
    head.add_row("start time", f"{result.start_time * 1e3:.3f} ms")
    if result.peak_force is not None:
        head.add_row("peak force", f"{result.peak_force:.1f} N at {result.peak_force_time * 1e3:.3f} ms")
        head.add_row("force offset removed", f"{result.force_offset:.3g} N")
        b = result.stage_b_start
        head.add_row("stage B (sustained contact) from", "none in record" if b is None else f"{b * 1e3:.3f} ms")
    for key, value in result.truth.items():
        head.add_row(f"truth {key}", f"{value:g}")
    channels = Table(title="channels")
    for column in ("name", "unit", "min", "max", "noise std (same unit)"):
        channels.add_column(column, justify="left" if column in ("name", "unit") else "right")
    for name, c in result.channels.items():
        channels.add_row(escape(name), escape(c.unit), f"{c.minimum:.4g}", f"{c.maximum:.4g}", f"{c.noise:.3g}")
    pulses = Table(title="contact pulses")
    for column in ("#", "start [ms]", "peak [ms]", "end [ms]", "peak force [N]", "impulse [N·s]", "stage"):
        pulses.add_column(escape(column), justify="right")
    for i, p in enumerate(result.pulses, start=1):
        pulses.add_row(str(i), f"{p.start * 1e3:.3f}", f"{p.peak_time * 1e3:.3f}", f"{p.end * 1e3:.3f}",
                       f"{p.peak_force:.1f}", f"{p.impulse:.4g}", "B" if p.sustained else "A")
    return [head, channels] + ([pulses] if result.pulses else [])


@app.command()
@reader_options
def inspect(
    file: Annotated[Path, typer.Argument(metavar="FILE", help="Recording (csv, h5, tdms, mat).")],
    plot: Annotated[Path | None, typer.Option("--plot", metavar="FILE",
                                              help="PNG of force and acceleration, pulses marked.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of tables.")] = False,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite the --plot file.")] = False,
    reader: ReaderOptions = DEFAULT_READER,
) -> None:
    """Print what FILE holds: duration, rate, channels and units, peak force, contact pulses, stage B, noise."""
    from ..identify.inspection import inspect_recording

    output_path(plot, overwrite, field="--plot", kind="figure")
    rec = reader.read(file)
    result = inspect_recording(rec)
    if as_json:
        console.print_json(json.dumps(result.to_dict()))
    else:
        for table in _inspection_tables(rec, result):
            console.print(table)
    if plot is not None:
        save_figure(result.plot(rec), plot)
        console.print(f"figure written to {plot}")
