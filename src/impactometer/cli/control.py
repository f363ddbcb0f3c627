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

#: rows of the metrics table: (label, key of AbsorptionMetrics.to_dict(), format); the whole event and R_B first,
#: then the supplementary columns (the run's own window, the control start)
TABLE_ROWS = (
    ("whole event: CFC 60 peak / F0 (ideal 1)", "whole_event_peak_ratio", lambda v: f"{v:.2f}"),
    ("  peak deceleration of the mass [g]", "peak_deceleration_g", lambda v: f"{v:.1f}"),
    ("  η = absorbed work / (peak × stroke used)", "whole_event_efficiency", lambda v: f"{v:.2f}"),
    ("  stroke used by the mass [mm]", "stroke_used_m", lambda v: f"{v * 1e3:.1f}"),
    ("  mass travel / usable stroke (pad included)", "stroke_utilisation", lambda v: f"{v:.2f}"),
    ("  time to stop [ms]", "time_to_stop_s", lambda v: f"{v * 1e3:.1f}"),
    ("  stopped", "stopped", lambda v: "yes" if v else "NO (cannot stop)"),
    ("  bottomed out (piston on the bottom stop)", "bottomed_out", lambda v: "YES" if v else "no"),
    ("  rebound [mm]", "rebound_m", lambda v: f"{v * 1e3:.1f}"),
    ("controller: R_B on the common window (ideal 1)", "stage_b_ratio", lambda v: f"{v:.2f}"),
    ("  CFC 60 peak in the window [N]", "stage_b_peak_force_N", lambda v: f"{v:.0f}"),
    ("  R_B,wide: from the first pulse's end + 1 ms", "wide_window_ratio", lambda v: f"{v:.2f}"),
    ("  control starts [ms]", "control_start_s", lambda v: f"{v * 1e3:.2f}"),
    ("  M1 estimated at the end [kg]", "estimated_mass_kg", lambda v: f"{v:.2f}"),
    ("supplementary: R on the run's own window", "own_window_force_ratio", lambda v: f"{v:.2f}"),
    ("  own window starts [ms]", "own_window_start_s", lambda v: f"{v * 1e3:.2f}"),
    ("  peak force, stage A [N]", "peak_force_stage_a_N", lambda v: f"{v:.0f}"),
    ("  peak force after control start [N]", "peak_force_controlled_N", lambda v: f"{v:.0f}"),
    ("  η after the control start", "controlled_efficiency", lambda v: f"{v:.3f}"),
)


def metrics_table(result) -> Table:
    """Rich table: one column per strategy (``auto`` named with the strategy it ran)."""
    from ..control.strategies import AUTO

    data = result.to_dict()
    ident = data["identification"]
    title = (f"{result.scenario.mass:g} kg at {result.scenario.velocity:.3f} m/s, p0 = "
             f"{result.scenario.pressure_gauge / 1e3:g} kPa; identification {ident['method']}")
    if ident["error"] is None and ident["method"] != "oracle":
        title += f": M1 = {ident['mass_kg']:.2f} kg, V0 = {ident['velocity_m_s']:.3f} m/s"
    window = (f"common window from {data['common_window_start_s'] * 1e3:.2f} ms (first sustained contact): "
              f"F_ref = {data['reference_force_N']:.0f} N, F_floor = {data['floor_force_N']:.0f} N"
              if data["common_window_start_s"] is not None else f"no common window: {data['common_window_excluded']}")
    usable = data["usable_stroke_m"] * 1e3
    table = Table(title=f"{title}\nF0 = {next(iter(data['strategies'].values()))['impact_force_N']:.0f} N; {window}",
                  caption=f"usable stroke {usable:.0f} mm: the controller's limit on the piston; the mass goes "
                          "further by the pad's compression")
    table.add_column("metric")
    for name in data["strategies"]:
        table.add_column(f"auto ({AUTO})" if name == "auto" else name, justify="right")
    for label, key, fmt in TABLE_ROWS:
        cells = []
        for values in data["strategies"].values():
            value = values.get(key)
            cells.append("—" if value is None else fmt(value))
        table.add_row(escape(label), *cells)
    if result.reference is not None:
        value = data["achievable_force_ratio"]
        table.add_row(escape(f"achievable R_B ({data['achievable_family'] or 'none feasible'})"),
                      *(["—" if value is None else f"{value:.2f}"] * len(data["strategies"])))
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
                                        help="Identification: model (the stand's model fitted as the record "
                                             "grows), robust, paper, oracle or response-map.")] = "model",
    map_path: Annotated[Path | None, typer.Option("--map", "--response-map", metavar="FILE",
                                                  help="Response map (.h5) for --method response-map.")] = None,
    noise: Annotated[str, typer.Option("--noise", metavar="FRACTION",
                                       help="Sensor noise, fraction of each channel's RMS (e.g. 2%).")] = "2%",
    seed: Annotated[int, typer.Option("--seed", help="Seed of the sensor noise.")] = 0,
    latency: Annotated[str, typer.Option(
        "--latency", metavar="TIME", help="Latency budget of the real-time system: the identification's answer is "
                                          "acted on this long after the last sample it used (default 1ms: a "
                                          "compiled real-time core).")] = "1ms",
    early: Annotated[bool, typer.Option(
        "--early/--wait", help="The policy: act from first contact on what is known (early, the default: V0 from "
                               "the first 0.5 ms of contact, M1's prior over the rated masses, refined as the mass "
                               "becomes known), or keep the valve closed until M1 is known (wait).")] = True,
    contact: ContactOpt = None,
    rig: Annotated[str, typer.Option("--rig", metavar="STAND", help="Stand: a preset name or a TOML file.")]
    = ABSORPTION_RIG,
    reference: Annotated[bool, typer.Option(
        "--reference", help="Also search the achievable R_B of this valve (about 250 more simulations).")] = False,
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
             f"{', '.join(names)}{'; then search the achievable R_B' if reference else ''}")
    with given(method=method, map=map_path, noise=noise, seed=seed, latency=latency), \
            announce_compilation(doing, compile_time="about 30-80 s"):
        result = run_absorb(scenario, stand, strategy=names, identification=method,
                            noise=quantity(noise, "fraction", "--noise"), seed=seed, response_map=map_path,
                            reference=reference, latency=quantity(latency, "time", "--latency"), early=early)
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
