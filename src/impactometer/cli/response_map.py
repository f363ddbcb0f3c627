"""``impactometer map build`` and ``impactometer map info``: response maps (paper section 5)."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ..errors import ParameterError
from .app import (
    OVERWRITE,
    App,
    QuietProgress,
    announce_compilation,
    app,
    console,
    error_console,
    given,
    output_path,
    quantity,
)
from .simulate import ContactOpt, RigOpt

map_app = App(help="Response maps: build a database of features, inspect it.")
app.add_typer(map_app, name="map")


def parse_grid(text: str, field: str = "--grid") -> tuple[int, int]:
    """``"10x10"`` (or ``"10"``) -> (10, 10); each size an integer >= 2."""
    parts = text.lower().replace("×", "x").split("x")
    try:
        sizes = [int(p) for p in parts]
    except ValueError:
        sizes = []
    if len(sizes) == 1:
        sizes = sizes * 2
    if len(sizes) != 2 or min(sizes) < 2:
        raise ParameterError(f"{field}: expected MASSESxVELOCITIES with integers >= 2 (e.g. 10x10), got {text!r}")
    return sizes[0], sizes[1]


def parse_range(text: str, dimension: str, field: str) -> tuple[float, float]:
    """``"10kg:50kg"`` -> (10.0, 50.0), low < high."""
    parts = text.split(":")
    if len(parts) != 2:
        raise ParameterError(f"{field}: expected LOW:HIGH (e.g. 10kg:50kg), got {text!r}")
    low, high = (quantity(p, dimension, field) for p in parts)
    if not 0 <= low < high:
        raise ParameterError(f"{field}: expected 0 <= LOW < HIGH, got {text!r}")
    return low, high


def parse_pressures(text: str) -> list[float]:
    """``"200kPa"`` or ``"20kPa,100kPa,400kPa"`` -> increasing list [Pa gauge]."""
    values = [quantity(p.strip(), "pressure", "--pressure") for p in text.split(",") if p.strip()]
    if not values or any(b <= a for a, b in zip(values, values[1:], strict=False)):
        raise ParameterError(f"--pressure: expected one pressure or an increasing comma list (e.g. "
                             f"20kPa,200kPa,400kPa), got {text!r}")
    return values


@map_app.command("build")
def build(
    out: Annotated[Path, typer.Option("--out", metavar="FILE", help="HDF5 file of the map.")],
    pressure: Annotated[str, typer.Option("--pressure", metavar="PRESSURE[,PRESSURE...]",
                                          help="Charge pressure (gauge); a comma list gives a pressure axis (e.g. "
                                               "20kPa,200kPa,400kPa).")] = "200kPa",
    grid: Annotated[str, typer.Option("--grid", metavar="MxV", help="Masses x velocities simulated (or "
                                                                     "interpolated).")] = "10x10",
    mass: Annotated[str, typer.Option("--mass", metavar="MASS:MASS", help="Mass range LOW:HIGH.")] = "10kg:50kg",
    height: Annotated[str | None, typer.Option("--height", metavar="LENGTH:LENGTH",
                                               help="Drop-height range LOW:HIGH (default 5cm:50cm).")] = None,
    velocity: Annotated[str | None, typer.Option("--velocity", metavar="VELOCITY:VELOCITY",
                                                 help="Velocity range LOW:HIGH instead of --height.")] = None,
    features: Annotated[str, typer.Option("--features", metavar="NAME", help="Feature set: max-impulse, peaks or "
                                                                             "impulse-profile.")] = "max-impulse",
    window: Annotated[str | None, typer.Option("--window", metavar="TIME", help="Window T of max-impulse and "
                                                                                "impulse-profile (default 20ms).")]
    = None,
    refine_to: Annotated[str | None, typer.Option("--refine", metavar="NxM", help="Interpolate to N (NxN) or "
                                                                                  "NxM.")] = None,
    sample_rate: Annotated[str, typer.Option("--sample-rate", metavar="FREQUENCY",
                                             help="Sample rate of the signals.")] = "50kHz",
    rig: RigOpt = None,
    contact: ContactOpt = None,
    from_recordings: Annotated[Path | None, typer.Option("--from-recordings", metavar="DIR",
                                                         help="Folder of calibration recordings.")] = None,
    manifest: Annotated[Path | None, typer.Option("--manifest", metavar="FILE",
                                                  help="Manifest CSV of the calibration set.")] = None,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite an existing map file.")] = False,
    device: Annotated[str, typer.Option("--device", metavar="NAME", help="Where the simulations run: cpu, gpu "
                                                                         "(extra impactometer[gpu]) or auto (the "
                                                                         "GPU when usable).")] = "cpu",
) -> None:
    """Build a response map by simulation (or from calibration recordings) and save it (HDF5)."""
    import numpy as np

    from ..identify.response_map import build_map_from_recordings, build_map_simulated, refine, save_map
    from ..identify.response_map.build import MAX_SIMULATED
    from ..identify.response_map.features import get_feature_set
    from ..model.gpu import resolve_device
    from ..rig import get_rig

    output_path(out, overwrite)
    if from_recordings is not None and device != "cpu":
        raise ParameterError(f"--device applies to maps built by simulation, got --device {device!r} with "
                             "--from-recordings")
    n_m, n_v = parse_grid(grid)
    params = {} if window is None else {"window": quantity(window, "time", "--window")}
    if window is not None and features not in ("max-impulse", "impulse-profile"):
        raise ParameterError(f"--window applies to --features max-impulse and impulse-profile, got --features "
                             f"{features!r}")
    with given(rig=rig, contact=contact):
        stand = get_rig(rig, contact=contact)
    if from_recordings is not None:
        from ..io import read_calibration_set

        recordings = read_calibration_set(from_recordings, manifest)
        rmap = build_map_from_recordings(recordings, grid=(n_m, n_v), features=features, feature_params=params,
                                         rig=stand if rig is not None or contact is not None else None,
                                         source=str(from_recordings))
    else:
        if height is not None and velocity is not None:
            raise ParameterError("give at most one of --height and --velocity, got both")
        masses = np.linspace(*parse_range(mass, "mass", "--mass"), n_m)
        if velocity is not None:
            velocities = np.linspace(*parse_range(velocity, "velocity", "--velocity"), n_v)
        else:
            low, high = parse_range(height or "5cm:50cm", "length", "--height")
            velocities = np.sqrt(2.0 * stand.gravity * np.linspace(low, high, n_v))
        pressures = parse_pressures(pressure)
        if pressures[-1] > stand.cylinder.rated_pressure_gauge:
            raise ParameterError(f"--pressure {pressure}: must be <= the rated "
                                 f"{stand.cylinder.rated_pressure_gauge:g} Pa of {stand.name!r}")
        with given(features=features, window=window, device=device):
            get_feature_set(features).params(params)  # bad features or a device the machine lacks: refused before
            resolve_device(device)  # any progress is printed
        if n_m * n_v * len(pressures) <= MAX_SIMULATED:  # (a larger grid is refused with the reason)
            print(f"simulating {n_m * n_v * len(pressures)} impacts ({n_m}×{n_v} grid, {len(pressures)} "
                  "pressure(s)) ...", file=sys.stderr, flush=True)
        with QuietProgress(console=error_console, transient=True, disable=not error_console.is_terminal,
                           redirect_stdout=False) as bar, \
                announce_compilation("simulating the response map", spinner=False):
            task = bar.add_task("simulating the response map", total=None)

            def progress(done: int, total: int) -> None:
                bar.update(task, completed=done, total=total)

            rmap = build_map_simulated(stand, pressures if len(pressures) > 1 else pressures[0], masses=masses,
                                       velocities=velocities, features=features, feature_params=params,
                                       sample_rate=quantity(sample_rate, "frequency", "--sample-rate"),
                                       progress=progress, device=device)
    if refine_to is not None:
        rmap = refine(rmap, parse_grid(refine_to, "--refine"))
    save_map(rmap, out, overwrite=overwrite)
    console.print(info_table(rmap.describe(), str(out)))
    console.print(f"map written to {out}")


def info_table(summary: dict, title: str) -> Table:
    """Rich table of :meth:`ResponseMap.describe`."""
    table = Table(title=title)
    table.add_column("field")
    table.add_column("value")
    pressures = summary["pressures_gauge_Pa"]
    rows = [
        ("schema version", str(summary["schema_version"])),
        ("feature set", f"{summary['feature_set']} {json.dumps(summary['feature_params'])}"),
        ("grid (masses × velocities)", "×".join(str(k) for k in summary["grid"])),
        ("mass range", "{:g} - {:g} kg".format(*summary["mass_range_kg"])),
        ("velocity range", "{:.4g} - {:.4g} m/s".format(*summary["velocity_range_m_s"])),
        ("charge pressure", ", ".join(f"{p / 1e3:g}" for p in pressures) + " kPa gauge"),
        ("sample rate", f"{summary['sample_rate_Hz']:g} Hz"),
        ("stand / contact law", f"{summary['stand']} / {summary['contact_law']}"),
        ("size", f"{summary['size_MB']:.3g} MB"),
    ]
    rows += [(f"feature {name}", f"{f['min']:.4g} - {f['max']:.4g} {f['unit']}")
             for name, f in summary["features"].items()]
    rows += [(f"provenance: {k}", v if isinstance(v, str) else json.dumps(v)) for k, v in summary["provenance"].items()]
    for name, value in rows:
        table.add_row(name, value)
    return table


@map_app.command("info")
def info(
    path: Annotated[Path, typer.Argument(metavar="FILE", help="Map file (HDF5).")],
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
) -> None:
    """Describe a response map: features, axes, pressure(s), stand and provenance (the file is validated)."""
    from ..identify.response_map import load_map

    summary = load_map(path).describe()
    if as_json:
        console.print_json(json.dumps(summary, default=lambda x: None if isinstance(x, float) and math.isnan(x)
                                      else str(x)))
    else:
        console.print(info_table(summary, str(path)))
