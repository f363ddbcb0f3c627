"""Figures of a calibration and a validation: each drop measured and simulated, with residuals (the paper's
Fig. 2), and a summary of the fitted parameters (matplotlib imported lazily)."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from . import ACCELERATION_LABEL, _pyplot, legend_outside


def _stem(source: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(source).stem)[:60] or "drop"


def plot_drop(drop, ax=None):
    """Figure of one drop (a :class:`~impactometer.calibrate.DropFit` or
    :class:`~impactometer.calibrate.DropValidation`): contact force [kN] and piston acceleration [m/s²], measured
    and simulated, vs time [ms], each with its residual below; returns the figure."""
    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(4, 1, figsize=(10, 8), sharex=True, constrained_layout=True,
                                 gridspec_kw={"height_ratios": [3, 1, 3, 1]})
    else:
        axes = list(ax)
        fig = axes[0].figure
    t = np.asarray(drop.time) * 1e3
    for row, (k, label, scale) in enumerate(((0, "contact force [kN]", 1e-3), (1, ACCELERATION_LABEL, 1.0))):
        unit = label[label.index("["):]
        top, bottom = axes[2 * row], axes[2 * row + 1]
        top.plot(t, drop.measured[k] * scale, color="0.55", lw=0.7, label="measured")
        top.plot(t, drop.simulated[k] * scale, color="C3", lw=1.0, label="simulated")
        top.set_ylabel(label)
        bottom.plot(t, (drop.measured[k] - drop.simulated[k]) * scale, color="C0", lw=0.6)
        bottom.axhline(0.0, color="k", lw=0.5)
        bottom.set_ylabel(f"residual {unit}")
    axes[-1].set_xlabel("time [ms]")
    legend_outside(axes[0])
    quality = getattr(drop, "force_nrmse", None)
    figure = f"force NRMSE {quality:.2%}" if quality is not None else f"chi2/dof {drop.reduced_chi2:.3g}"
    axes[0].set_title(f"{Path(drop.source).name}: M1 = {drop.mass:.4g} kg, V0 = {drop.velocity:.4g} m/s, "
                      f"p0 = {drop.pressure_gauge / 1e3:.4g} kPa; {figure}")
    return fig


def plot_drops(drops: Sequence, folder: str | Path, *, prefix: str) -> list[Path]:
    """:func:`plot_drop` of each drop, written to ``folder`` as ``PREFIX-NN-FILE.png``; returns the paths."""
    plt = _pyplot()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, drop in enumerate(drops):
        fig = plot_drop(drop)
        path = folder / f"{prefix}-{i + 1:02d}-{_stem(drop.source)}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def plot_parameters(calibration, ax=None):
    """Summary of a :class:`~impactometer.calibrate.Calibration`: each parameter's relative standard error [%],
    their correlation matrix, and each drop's χ²/dof; returns the figure."""
    from ..rig.display import display_unit

    plt = _pyplot()
    if ax is None:
        fig, axes = plt.subplots(1, 3, figsize=(14, 4.5), constrained_layout=True)
    else:
        axes = list(ax)
        fig = axes[0].figure
    names = list(calibration.parameters)
    relative = [100.0 * calibration.std[n] / abs(calibration.parameters[n]) if calibration.parameters[n] else np.nan
                for n in names]
    axes[0].barh(names, relative, color="C0")
    axes[0].set_xscale("log")
    axes[0].set_xlabel("standard error [% of the value]")
    for y, n in enumerate(names):
        unit, factor = display_unit(n, calibration.law)
        axes[0].annotate(f"{calibration.parameters[n] * factor:.4g} {unit}", (relative[y], y), fontsize=8,
                         va="center", xytext=(3, 0), textcoords="offset points")
    image = axes[1].imshow(calibration.correlation, vmin=-1.0, vmax=1.0, cmap="RdBu_r")
    axes[1].set_xticks(range(len(names)), [n.split(".")[-1] for n in names], rotation=45, ha="right")
    axes[1].set_yticks(range(len(names)), [n.split(".")[-1] for n in names])
    fig.colorbar(image, ax=axes[1], label="correlation [-]")
    chi2 = [d.reduced_chi2 for d in calibration.drops]
    colours = ["C3" if d.inconsistent else "C2" for d in calibration.drops]
    axes[2].bar(range(1, len(chi2) + 1), chi2, color=colours)
    axes[2].axhline(1.0, color="k", lw=0.8)
    axes[2].set_xlabel("drop [-] (red: inconsistent with the others)")
    axes[2].set_ylabel("chi2/dof [-]")
    fig.suptitle(f"{calibration.rig.name}: {calibration.law} contact, chi2/dof = {calibration.reduced_chi2:.3g}")
    return fig


def plot_calibration(calibration, folder: str | Path) -> list[Path]:
    """Every figure of a calibration written to ``folder``: one per drop and ``calibrate-parameters.png``."""
    plt = _pyplot()
    paths = plot_drops(calibration.drops, folder, prefix="calibrate")
    fig = plot_parameters(calibration)
    path = Path(folder) / "calibrate-parameters.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return [*paths, path]
