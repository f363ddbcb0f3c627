"""``impactometer calibrate`` (a stand from drops of known mass) and ``impactometer validate`` (a stand on held-back
drops)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.markup import escape
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


def _inputs(sources: list[Path], manifest: Path | None, rig: str | None) -> list[Path]:
    """Every file a command reads: the recordings (a folder's files), the manifest and a stand file."""
    files = []
    for source in sources:
        files += [p for p in source.iterdir() if p.is_file()] if source.is_dir() else [source]
    files += [p for p in (manifest, Path(rig) if rig else None) if p is not None]
    return files


def check_targets(out: Path | None, plot: Path | None, sources: list[Path], manifest: Path | None,
                  rig: str | None) -> None:
    """Refuse, before any work, an ``--out`` that is not a ``.toml`` file or is one of the inputs, and a ``--plot``
    folder that is the ``--out`` file or a folder of recordings."""
    def same(a: Path, b: Path) -> bool:
        return a.resolve() == b.resolve()

    if out is not None:
        if out.suffix.lower() != ".toml":
            raise ParameterError(f"--out {out}: the stand file must end in .toml, got "
                                 f"{repr(out.suffix) if out.suffix else 'no extension'}")
        clash = next((p for p in _inputs(sources, manifest, rig) if same(out, p)), None)
        if clash is not None:
            raise ParameterError(f"--out {out}: it is one of the inputs ({clash}); write the stand to another file")
    if plot is not None:
        if out is not None and same(plot, out):
            raise ParameterError(f"--plot {plot}: it is the --out file; give a folder for the figures")
        clash = next((p for p in sources if p.is_dir() and same(plot, p)), None)
        if clash is not None:
            raise ParameterError(f"--plot {plot}: it is the folder of recordings; give another folder for the "
                                 "figures")


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


def _progress(bar, task, what: str):
    """The progress callback: the bar on a terminal; elsewhere (a log, a pipe) one plain line per stage on
    standard error."""
    def progress(done: int, total: int) -> None:
        if error_console.is_terminal:
            bar.update(task, completed=done, total=total)
        else:
            print(f"{what}: stage {done} of {total} done", file=sys.stderr, flush=True)
    return progress


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
    exclude: Annotated[list[str] | None, typer.Option("--exclude", metavar="FILE", help="Leave this drop out of "
                                                                                         "the fit (repeatable).")]
    = None,
    drop_outliers: Annotated[bool, typer.Option("--drop-outliers", help="Fit the stand once more without the drops "
                                                                         "named inconsistent with the others.")]
    = False,
    as_json: JsonOpt = False,
    overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite the --out file and --plot figures.")]
    = False,
) -> None:
    """Calibrate a stand model from drops of known mass, light-gate velocity and charge pressure."""
    from ..calibrate import calibrate, check_inputs

    output_path(out, overwrite)
    check_targets(out, plot, sources, manifest, rig)
    plot_folder(plot, overwrite)
    sigma = quantity(velocity_sigma, "fraction", "--velocity-sigma")
    length = None if duration.strip().lower() == "all" else quantity(duration, "time", "--duration")
    recordings = read_drops(sources, manifest)
    options: dict[str, Any] = {"rig": rig, "fit": fit, "contact": contact, "velocity_sigma": sigma, "duration": length,
                              "exclude": exclude or None, "drop_outliers": drop_outliers}
    with given(rig=rig, fit=fit, contact=contact, velocity_sigma=velocity_sigma, duration=duration,
               exclude=",".join(exclude) if exclude else None):
        check_inputs(recordings, **options)
    used = len(recordings) - len(set(exclude or ()))
    with _bar() as bar, announce_compilation("calibrating", spinner=False):
        task = bar.add_task(f"calibrating on {used} drops", total=None)
        with given(rig=rig, fit=fit, contact=contact, velocity_sigma=velocity_sigma, duration=duration,
                   exclude=",".join(exclude) if exclude else None):
            result = calibrate(recordings, **options, progress=_progress(bar, task, f"calibrating on {used} drops"))
    result.to_toml(out, overwrite=overwrite)
    figures = result.plot(plot) if plot is not None else []
    if as_json:
        typer.echo(json.dumps({**result.to_dict(), "out": str(out), "figures": [str(p) for p in figures]}))
        return
    console.print(calibration_table(result))
    console.print(drops_table(result))
    for line in result.warnings:
        console.print(f"warning: {line}", markup=False, highlight=False)
    state = "" if result.fits else " (flagged: the stand does not fit its drops)"
    console.print(f"stand written to {out}{state}" + (f"; {len(figures)} figures in {plot}" if figures else ""),
                  markup=False, highlight=False)


def calibration_table(result: Calibration) -> Table:
    """Rich table of a calibration: families, parameters (with their units), what the drops do not tell apart."""
    from ..rig.display import display_unit

    table = Table(title=f"{result.rig.name}: {result.law} contact, chi2/dof = {result.reduced_chi2:.4g}, misfit "
                        f"{result.misfit_sigma:.3g} sigma" + ("" if result.fits else " (does not fit)"))
    table.add_column("item")
    table.add_column("value")
    for law, fam in result.families.items():
        text = (f"chi2/dof {fam['reduced_chi2']:.4g}, BIC {fam['bic']:.6g}" if "bic" in fam else
                fam.get("dropped") or fam.get("error", ""))
        table.add_row(f"family {law}" + (" (chosen)" if law == result.law else ""), text)
    for name, value in result.parameters.items():
        unit, factor = display_unit(name, result.law)
        table.add_row(escape(f"{name} [{unit}]"), with_uncertainty(value * factor, result.std[name] * factor))
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


def drops_table(result: Calibration) -> Table:
    """Rich table of the drops of a calibration: truth, fitted V0, residuals and agreement with the others."""
    table = Table(title=f"drops (named inconsistent beyond {result.drops[0].limit:.2f} sigma of light-gate pull, "
                        "misfit or half the influence, and 3 times the set's median)")
    for column in ("drop", "M1 [kg]", "p0 [kPa]", "V0 gate / fitted [m/s]", "gate pull [sigma]", "chi2/dof",
                   "misfit [sigma]", "NRMSE", "infl. [sigma]", "verdict"):
        # "[kg]" is no markup; the names and the velocities are not broken over lines
        table.add_column(escape(column), no_wrap=column in ("drop", "V0 gate / fitted [m/s]", "verdict"))
    for d in result.drops:
        table.add_row(Path(d.source).name, f"{d.mass:g}", f"{d.pressure_gauge / 1e3:g}",
                      f"{d.velocity_gate:.4g} / {with_uncertainty(d.velocity, d.velocity_std)}",
                      f"{d.velocity_pull:+.1f}", f"{d.reduced_chi2:.4g}", f"{d.misfit_sigma:.1f}",
                      f"{d.force_nrmse:.2%}", f"{d.influence_sigma:.1f}",
                      "inconsistent" if d.inconsistent else "consistent")
    for item in result.excluded:
        table.add_row(Path(item["file"]).name, *[""] * 8, "left out")
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
    from ..rig import PRESETS, get_rig

    check_targets(None, plot, sources, manifest, None)
    plot_folder(plot, overwrite)
    if stand not in PRESETS and Path(stand).suffix.lower() != ".toml":
        raise ParameterError(f"STAND {stand}: the stand must be a stand TOML file (e.g. one calibrate wrote) or a "
                             f"preset name ({', '.join(sorted(PRESETS))}); the drops follow it")
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
    limit = result.drops[0].model_error_limit
    table = Table(title=f"{result.stand} ({result.contact_law}): median force NRMSE "
                        f"{result.median_force_nrmse:.2%}; {result.reproduced} of {len(result.drops)} drops "
                        f"reproduced (force error beyond the noise <= {limit:.0%} of the force range)")
    for column in ("drop", "M1 [kg]", "V0 [m/s]", "p0 [kPa]", "force NRMSE [% of range]", "noise alone [%]",
                   "beyond noise [%]", "peak force [%]", "first pulse [ms]", "stage B [ms]", "verdict"):
        table.add_column(escape(column))  # "[kg]" is no markup

    def ms(value):
        return "-" if value is None else f"{value * 1e3:+.3f}"

    for d in result.drops:
        table.add_row(Path(d.source).name, f"{d.mass:g}", f"{d.velocity:g}", f"{d.pressure_gauge / 1e3:g}",
                      f"{d.force_nrmse:.2%}", f"{d.noise_nrmse:.2%}", f"{d.model_error:.2%}",
                      f"{d.peak_force_error:+.2%}", ms(d.first_pulse_error), ms(d.stage_b_error),
                      "reproduced" if d.reproduced else "not reproduced")
    return table
