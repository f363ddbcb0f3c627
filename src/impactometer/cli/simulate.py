"""``impactometer simulate`` and ``impactometer demo``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ..errors import ParameterError
from ..outputs import save_figure, write_failed
from ..rig import Scenario, get_rig
from .app import OVERWRITE, announce_compilation, app, console, given, output_path, quantity

MassOpt = Annotated[str, typer.Option("--mass", metavar="MASS", help="Impacting mass M1 (e.g. 30kg).")]
HeightOpt = Annotated[str | None, typer.Option("--height", metavar="LENGTH",
                                               help="Drop height h, V0 = sqrt(2gh) (e.g. 0.2m).")]
VelocityOpt = Annotated[str | None, typer.Option("--velocity", metavar="VELOCITY",
                                                 help="Impact velocity V0 (e.g. 2m/s).")]
PressureOpt = Annotated[str, typer.Option("--pressure", metavar="PRESSURE",
                                          help="Charge pressure p0, gauge (e.g. 200kPa).")]
ContactOpt = Annotated[str | None, typer.Option(
    "--contact", metavar="LAW", help="Contact law: hysteretic, kelvin-voigt (kv), hunt-crossley (hunt) or power "
                                     "(masing) (default: the stand's own, hysteretic on drop-stand).")]
RigOpt = Annotated[str | None, typer.Option("--rig", metavar="STAND",
                                            help="Stand: a preset name or a TOML file (default: drop-stand).")]
DurationOpt = Annotated[str, typer.Option("--duration", metavar="TIME", help="Simulated time after first contact.")]
RateOpt = Annotated[str, typer.Option("--sample-rate", metavar="FREQUENCY", help="Sample rate of the histories.")]


def stand_and_scenario(mass: str, height: str | None, velocity: str | None, pressure: str, *, rig: str | None,
                       contact: str | None, default_height: str = "0.2m"):
    """The (stand, scenario) of a command's options (neither height nor velocity: ``default_height``)."""
    with given(rig=rig, contact=contact, mass=mass, height=height, velocity=velocity, pressure=pressure):
        stand = get_rig(rig, contact=contact)
        m = quantity(mass, "mass", "--mass")
        p0 = quantity(pressure, "pressure", "--pressure")
        if height is not None and velocity is not None:
            raise ParameterError(f"give exactly one of --height and --velocity (neither: a drop from "
                                 f"{default_height}), got both")
        if velocity is not None:
            scenario = Scenario(mass=m, velocity=quantity(velocity, "velocity", "--velocity"), pressure_gauge=p0)
        else:
            scenario = Scenario.from_height(mass=m, height=quantity(height or default_height, "length", "--height"),
                                            pressure_gauge=p0, gravity=stand.gravity)
        scenario.check_against(stand)
    return stand, scenario


#: step budget of the reference integrator from the command line: a fixed part and a part per simulated second
#: (a drop test needs about 2000 steps per 0.1 s; beyond the budget the stand or scenario is too stiff to simulate
#: in reasonable time, and the command fails in seconds instead of running for hours)
REFERENCE_STEPS = (20_000, 100_000)


def reference_steps(duration: float) -> int:
    """Step budget of ``simulate --integrator reference`` for ``duration`` [s]."""
    fixed, per_second = REFERENCE_STEPS
    return int(fixed + per_second * min(max(duration, 0.0), 1e3))


def summary_table(result, title: str) -> tuple[Table, list]:
    """Rich table of the headline numbers of a simulation."""
    from ..signals.pulses import contact_pulses
    from ..signals.stage_b import stage_b_start

    pulses = contact_pulses(result.time, result.contact_force)
    b = stage_b_start(pulses)
    table = Table(title=title)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    rows = [
        ("impact velocity V0", f"{result.scenario.velocity:.4f} m/s"),
        ("impact energy", f"{0.5 * result.scenario.mass * result.scenario.velocity ** 2:.2f} J"),
        ("peak contact force", f"{result.contact_force.max():.1f} N"),
        ("contact pulses (stage A)", f"{sum(not p.sustained for p in pulses)}"),
        ("stage B (sustained contact) from", "none in record" if b is None else f"{b * 1e3:.2f} ms"),
        ("max stroke", f"{result.u2.max() * 1e3:.2f} mm"),
        ("peak pressure, lower chamber", f"{result.pressure_lower.max() / 1e3:.1f} kPa abs"),
        ("peak pressure, upper chamber", f"{result.pressure_upper.max() / 1e3:.1f} kPa abs"),
        (f"energy dissipated in the first {result.time[-1] * 1e3:.0f} ms", f"{result.dissipated_energy[-1]:.3f} J"),
        ("energy balance error", f"{result.energy_balance_error:.2e} of E0"),
    ]
    for name, value in rows:
        table.add_row(name, value)
    return table, pulses


@app.command()
def simulate(
    mass: MassOpt = "30kg",
    height: HeightOpt = None,
    velocity: VelocityOpt = None,
    pressure: PressureOpt = "200kPa",
    contact: ContactOpt = None,
    rig: RigOpt = None,
    duration: DurationOpt = "50ms",
    sample_rate: RateOpt = "50kHz",
    integrator: Annotated[str, typer.Option(metavar="NAME", help="fast (compiled) or reference (solve_ivp).")]
    = "fast",
    out: Annotated[Path | None, typer.Option("--out", metavar="FILE", help="HDF5 file of the histories.")] = None,
    plot: Annotated[Path | None, typer.Option("--plot", metavar="FILE", help="PNG figure of the histories.")] = None,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite existing output files.")] = False,
) -> None:
    """Simulate one drop test on the stand and save its histories (HDF5) and a figure."""
    from ..model import simulate as run_simulation
    from ..model.io import save_simulation

    stand, scenario = stand_and_scenario(mass, height, velocity, pressure, rig=rig, contact=contact)
    output_path(out, overwrite, kind="hdf5")
    output_path(plot, overwrite, field="--plot", kind="figure")
    with announce_compilation("simulating the drop and finding its contact pulses"):
        with given(duration=duration, integrator=integrator, sample_rate=sample_rate):
            length = quantity(duration, "time", "--duration")
            budget = {"max_steps": reference_steps(length)} if integrator == "reference" else {}
            result = run_simulation(scenario, stand, duration=length, integrator=integrator,
                                    sample_rate=quantity(sample_rate, "frequency", "--sample-rate"), **budget)
        table, pulses = summary_table(result, f"{scenario.mass:g} kg at {scenario.velocity:.3f} m/s, "
                                              f"p0 = {scenario.pressure_gauge / 1e3:g} kPa ({stand.contact.law})")
    console.print(table)
    if out is not None:
        try:
            save_simulation(result, out, overwrite=overwrite)
        except OSError as exc:
            raise write_failed(out, exc) from None
        console.print(f"histories written to {out}")
    if plot is not None:
        save_figure(result.plot(pulses=pulses), plot)
        console.print(f"figure written to {plot}")
