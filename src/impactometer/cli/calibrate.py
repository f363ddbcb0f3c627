"""``impactometer calibrate`` (a stand from drops of known mass) and ``impactometer validate`` (a stand on held-back
drops)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from ..errors import ParameterError
from .app import (
    OVERWRITE,
    QuietProgress,
    announce_compilation,
    app,
    console,
    error_console,
    given,
    output_path,
    quantity,
    with_uncertainty,
)

if TYPE_CHECKING:
    from ..calibrate import Calibration, Validation

SourcesArg = Annotated[list[Path], typer.Argument(
    metavar="FOLDER|FILE", help="A folder of drop recordings with manifest.csv (file,mass_kg,velocity_m_s,"
                                   "pressure_gauge_Pa), or recording files that state their truth.")]
ManifestOpt = Annotated[Path | None, typer.Option("--manifest", metavar="FILE",
                                                  help="Manifest CSV of a FOLDER (default FOLDER/manifest.csv).")]
PlotOpt = Annotated[Path | None, typer.Option("--plot", metavar="DIR", help="Folder for one figure per drop (and a "
                                                                           "parameter summary).")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print the result as JSON.")]


def read_drops(sources: list[Path], manifest: Path | None):
    """The recordings of a folder (with its manifest) or of the files given (each stating its truth)."""
    from ..io import read_calibration_set, read_recording

    if len(sources) == 1 and sources[0].is_dir():
        return read_calibration_set(sources[0], manifest)
    if manifest is not None:
        raise ParameterError(f"--manifest applies to a FOLDER of recordings, got {len(sources)} file(s)")
    folders = [str(p) for p in sources if p.is_dir()]
    if folders:
        raise ParameterError(f"give one FOLDER or recording files, got the folder {folders[0]} among "
                             f"{len(sources)} paths")
    return [read_recording(path) for path in sources]


def plot_folder(folder: Path | None, overwrite: bool) -> None:
    """Refuse a ``--plot`` folder that is a file, or that holds files already, unless ``--overwrite``."""
    if folder is None:
        return
    if folder.exists() and not folder.is_dir():
        raise ParameterError(f"--plot {folder}: not a folder; expected a folder for the figures")
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise ParameterError(f"--plot {folder}: the folder holds files already; give an empty or new folder, or "
                             "--overwrite to replace its figures")


def _bar():
    return QuietProgress(console=error_console, transient=True, disable=not error_console.is_terminal,
                         redirect_stdout=False)


@app.command("calibrate")
def calibrate_command(
    sources: SourcesArg,
    out: Annotated[Path, typer.Option("--out", metavar="FILE", help="Calibrated stand file (TOML).")],
    rig: Annotated[str | None, typer.Option("--rig", metavar="STAND", help="Base stand: a preset name or a TOML "
                                                                          "file (its geometry, piston mass and gas "
                                                                          "are kept).")] = None,
    fit: Annotated[str | None, typer.Option("--fit", metavar="NAMES", help="Stand parameters fitted, comma "
                                                                           "separated (default: contact, "
                                                                           "friction.force, both dead volumes; "
                                                                           "'default' names those).")] = None,
    contact: Annotated[str, typer.Option("--contact", metavar="LAW", help="auto (every contact-law family, the "
                                                                          "smallest BIC) or one law.")] = "auto",
    velocity_sigma: Annotated[str, typer.Option("--velocity-sigma", metavar="FRACTION",
                                                help="Relative sigma of the light-gate velocities.")] = "0.5%",
    duration: Annotated[str, typer.Option("--duration", metavar="TIME", help="Length of each record fitted after "
                                                                             "first contact ('all': whole "
                                                                             "records).")] = "60ms",
    manifest: ManifestOpt = None,
    plot: PlotOpt = None,
    as_json: JsonOpt = False,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite the --out file and --plot figures.")]
    = False,
) -> None:
    """Calibrate a stand model from drops of known mass, light-gate velocity and charge pressure."""
    from ..calibrate import calibrate, check_inputs

    output_path(out, overwrite)
    plot_folder(plot, overwrite)
    sigma = quantity(velocity_sigma, "fraction", "--velocity-sigma")
    length = None if duration.strip().lower() == "all" else quantity(duration, "time", "--duration")
    recordings = read_drops(sources, manifest)
    with given(rig=rig, fit=fit, contact=contact, velocity_sigma=velocity_sigma, duration=duration):
        check_inputs(recordings, rig=rig, fit=fit, contact=contact, velocity_sigma=sigma, duration=length)
    with _bar() as bar, announce_compilation("calibrating", spinner=False):
        task = bar.add_task(f"calibrating on {len(recordings)} drops", total=None)
        with given(rig=rig, fit=fit, contact=contact, velocity_sigma=velocity_sigma, duration=duration):
            result = calibrate(recordings, rig=rig, fit=fit, contact=contact, velocity_sigma=sigma, duration=length,
                               progress=lambda done, total: bar.update(task, completed=done, total=total))
    result.to_toml(out, overwrite=overwrite)
    figures = result.plot(plot) if plot is not None else []
    if as_json:
        typer.echo(json.dumps({**result.to_dict(), "out": str(out), "figures": [str(p) for p in figures]}))
        return
    console.print(calibration_table(result))
    for line in result.warnings:
        console.print(f"warning: {line}", markup=False, highlight=False)
    console.print(f"stand written to {out}" + (f"; {len(figures)} figures in {plot}" if figures else ""),
                  markup=False, highlight=False)


def calibration_table(result: Calibration) -> Table:
    """Rich table of a calibration: families, parameters, drops, what the drops do not tell apart."""
    table = Table(title=f"{result.rig.name}: {result.law} contact, chi2/dof = {result.reduced_chi2:.4g}"
                        + ("" if result.fits else " (does not fit)"))
    table.add_column("item")
    table.add_column("value")
    for law, fam in result.families.items():
        text = (f"chi2/dof {fam['reduced_chi2']:.4g}, BIC {fam['bic']:.6g}" if "bic" in fam else
                fam.get("dropped") or fam.get("error", ""))
        table.add_row(f"family {law}" + (" (chosen)" if law == result.law else ""), text)
    for name, value in result.parameters.items():
        table.add_row(name, with_uncertainty(value, result.std[name]))
    for drop in result.drops:
        table.add_row(f"drop {Path(drop.source).name}", f"M1 {drop.mass:g} kg, V0 "
                      f"{with_uncertainty(drop.velocity, drop.velocity_std, 'm/s')} (gate {drop.velocity_gate:g}), "
                      f"chi2/dof {drop.reduced_chi2:.4g}")
    for item in result.indistinct:
        names = " and ".join(item["parameters"])
        hint = item.get("suggestion")
        advice = "" if not hint else (f"; add a drop of another {hint['kind']}: M1 {hint['mass_kg']:.4g} kg, V0 "
                                      f"{hint['velocity_m_s']:.4g} m/s, p0 {hint['pressure_gauge_Pa'] / 1e3:.4g} kPa "
                                      f"(|corr| {hint['largest_correlation_before']:.3f} -> "
                                      f"{hint['largest_correlation_after']:.3f})")
        what = "undetermined" if item.get("undetermined") else f"correlation {item['correlation']:+.3f}"
        table.add_row(f"not told apart: {names}", what + advice)
    return table


@app.command("validate")
def validate_command(
    stand: Annotated[str, typer.Argument(metavar="STAND", help="The stand: a TOML file (e.g. calibrated) or a "
                                                               "preset name.")],
    sources: SourcesArg,
    manifest: ManifestOpt = None,
    plot: PlotOpt = None,
    as_json: JsonOpt = False,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite --plot figures.")] = False,
) -> None:
    """Reproduce held-back drops of known mass, velocity and pressure with a stand and report how well."""
    from ..calibrate import validate
    from ..rig import get_rig

    plot_folder(plot, overwrite)
    with given(rig=stand):
        rig = get_rig(stand)
    recordings = read_drops(sources, manifest)
    with announce_compilation("validating"):
        result = validate(rig, recordings)
    figures = result.plot(plot) if plot is not None else []
    if as_json:
        typer.echo(json.dumps({**result.to_dict(), "figures": [str(p) for p in figures]}))
        return
    console.print(validation_table(result))
    if figures:
        console.print(f"{len(figures)} figures in {plot}", markup=False, highlight=False)


def validation_table(result: Validation) -> Table:
    """Rich table of a validation, one row per drop."""
    table = Table(title=f"{result.stand} ({result.contact_law}): median force NRMSE "
                        f"{result.median_force_nrmse:.2%}")
    for column in ("drop", "M1 [kg]", "V0 [m/s]", "p0 [kPa]", "force NRMSE", "noise alone", "peak force",
                   "first pulse [ms]", "stage B [ms]"):
        table.add_column(column)

    def ms(value):
        return "-" if value is None else f"{value * 1e3:+.3f}"

    for d in result.drops:
        table.add_row(Path(d.source).name, f"{d.mass:g}", f"{d.velocity:g}", f"{d.pressure / 1e3:g}",
                      f"{d.force_nrmse:.2%}", f"{d.noise_nrmse:.2%}", f"{d.peak_force_error:+.2%}",
                      ms(d.first_pulse_error), ms(d.stage_b_error))
    return table
