"""``impactometer absorb``: the closed loop identify → control on one impact, every strategy side by side."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from ..errors import ParameterError
from ..rig import ABSORPTION_RIG
from .app import OVERWRITE, announce_compilation, app, console, given, output_path, quantity
from .simulate import ContactOpt, HeightOpt, MassOpt, PressureOpt, VelocityOpt, stand_and_scenario

#: rows of the metrics table: (label, key of AbsorptionMetrics.to_dict(), format)
TABLE_ROWS = (
    ("control starts [ms]", "control_start_s", lambda v: f"{v * 1e3:.2f}"),
    ("stage B starts [ms]", "stage_b_start_s", lambda v: f"{v * 1e3:.2f}"),
    ("reference force F_ref [N]", "reference_force_N", lambda v: f"{v:.0f}"),
    ("stage-B force ratio R (ideal 1)", "stage_b_force_ratio", lambda v: f"{v:.2f}"),
    ("stage-B efficiency η_B", "stage_b_efficiency", lambda v: f"{v:.2f}"),
    ("M1 estimated at the end [kg]", "estimated_mass_kg", lambda v: f"{v:.2f}"),
    ("peak force, stage A [N]", "peak_force_stage_a_N", lambda v: f"{v:.0f}"),
    ("peak force after control start [N]", "peak_force_controlled_N", lambda v: f"{v:.0f}"),
    ("  same, CFC 60 body load [N]", "peak_force_controlled_cfc60_N", lambda v: f"{v:.0f}"),
    ("max deceleration after start [m/s²]", "max_deceleration_m_s2", lambda v: f"{v:.0f}"),
    ("energy absorbed after start [J]", "energy_absorbed_J", lambda v: f"{v:.1f}"),
    ("bounce energy at start [J]", "bounce_energy_J", lambda v: f"{v:.2f}"),
    ("efficiency η", "efficiency", lambda v: f"{v:.3f}"),
    ("  η with CFC 60 force", "efficiency_cfc60", lambda v: f"{v:.3f}"),
    ("stroke used [mm]", "stroke_used_m", lambda v: f"{v * 1e3:.1f}"),
    ("bottomed out", "bottomed_out", lambda v: "YES" if v else "no"),
    ("time to stop [ms]", "time_to_stop_s", lambda v: f"{v * 1e3:.1f}"),
    ("rebound [mm]", "rebound_m", lambda v: f"{v * 1e3:.1f}"),
)


def metrics_table(result) -> Table:
    """Rich table: one column per strategy."""
    data = result.to_dict()
    ident = data["identification"]
    title = (f"{result.scenario.mass:g} kg at {result.scenario.velocity:.3f} m/s, p0 = "
             f"{result.scenario.pressure_gauge / 1e3:g} kPa; identification {ident['method']}")
    if ident["error"] is None and ident["method"] != "oracle":
        title += f": M1 = {ident['mass_kg']:.2f} kg, V0 = {ident['velocity_m_s']:.3f} m/s"
    table = Table(title=title)
    table.add_column("metric")
    for name in data["strategies"]:
        table.add_column(name, justify="right")
    for label, key, fmt in TABLE_ROWS:
        cells = []
        for values in data["strategies"].values():
            value = values.get(key)
            cells.append("—" if value is None else fmt(value))
        table.add_row(escape(label), *cells)
    for label, key in (("bound η_max (all strategies)", "efficiency_max"),
                       ("  with the first-collision peak", "efficiency_first_collision")):
        value = data[key]
        table.add_row(label, *(["—" if value is None else f"{value:.3f}"] * len(data["strategies"])))
    if result.reference is not None:
        value = data["achievable_force_ratio"]
        table.add_row("achievable R of this valve", *(["—" if value is None else f"{value:.2f}"]
                                                       * len(data["strategies"])))
    return table


@app.command()
def absorb(
    mass: MassOpt = "30kg",
    height: HeightOpt = None,
    velocity: VelocityOpt = None,
    pressure: PressureOpt = "200kPa",
    strategy: Annotated[str, typer.Option(
        "--strategy", metavar="NAME", help="all, closed, constant, realtime, predictive or auto (the better of the "
                                           "two).")] = "all",
    method: Annotated[str, typer.Option("--method", "--identify", metavar="NAME",
                                        help="Identification: robust, paper, oracle or response-map.")] = "robust",
    map_path: Annotated[Path | None, typer.Option("--map", "--response-map", metavar="FILE",
                                                  help="Response map (.h5) for --method response-map.")] = None,
    noise: Annotated[str, typer.Option("--noise", metavar="FRACTION",
                                       help="Sensor noise, fraction of each channel's RMS (e.g. 2%).")] = "2%",
    seed: Annotated[int, typer.Option("--seed", help="Seed of the sensor noise.")] = 0,
    contact: ContactOpt = None,
    rig: Annotated[str, typer.Option("--rig", metavar="STAND", help="Stand: a preset name or a TOML file.")]
    = ABSORPTION_RIG,
    reference: Annotated[bool, typer.Option(
        "--reference", help="Also search the achievable R of this valve (a dozen more simulations).")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print the metrics as one JSON object.")] = False,
    plot: Annotated[Path | None, typer.Option("--plot", metavar="FILE",
                                              help="PNG figure of the force histories (Fig. 10b).")] = None,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite an existing figure.")] = False,
) -> None:
    """Absorb one impact: identify M1 and V0 from noisy sensors, then control valve Z with each strategy (on the
    built-in pad stand, drop-stand, unless --rig says otherwise)."""
    from ..control.loop import absorb as run_absorb  # compiled code: imported when used
    from ..control.strategies import strategy_names

    stand, scenario = stand_and_scenario(mass, height, velocity, pressure, rig=rig, contact=contact,
                                         default_height="0.3m")
    with given(strategy=strategy):
        names = strategy_names(strategy)
    output_path(plot, overwrite, field="--plot", kind="figure")
    if map_path is not None and method != "response-map":
        raise ParameterError(f"--map is only used with --method response-map, got --method {method}")
    if map_path is not None and not map_path.is_file():
        raise ParameterError(f"--map: {str(map_path)!r} does not exist")
    doing = (f"closed loop on {stand.name}: identify M1 and V0 ({method}), then control valve Z with "
             f"{', '.join(names)}{'; then search the achievable R' if reference else ''}")
    with given(method=method, map=map_path, noise=noise, seed=seed), \
            announce_compilation(doing, compile_time="about 30-80 s"):
        result = run_absorb(scenario, stand, strategy=names, identification=method,
                            noise=quantity(noise, "fraction", "--noise"), seed=seed, response_map=map_path,
                            reference=reference)
    if as_json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
    else:
        console.print(metrics_table(result))
        for note in result.notes:
            console.print(f"[yellow]note:[/yellow] {escape(note)}")
    if plot is not None:
        from ..outputs import save_figure

        save_figure(result.plot(), plot)
        if not as_json:
            console.print(f"figure written to {plot}")
