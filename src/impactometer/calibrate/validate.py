"""Validation of a stand on drops it was not calibrated on: each drop of known M1, V0 (the light gate's, held)
and p0 is simulated with the stand through the recording's sensor model, only the contact instant (between
samples) and the two sensor offsets fitted, and compared with the record.

Figures per drop: the force NRMSE, RMS(measured − simulated)/(max − min of the measured force) over the record
from first contact [-], beside the share of it the noise alone gives (the pre-trigger σ over the same range); the
peak-force error (simulated − measured)/measured [-]; the timing errors (simulated − measured) [s] of the end of
the first contact pulse and of the start of stage B, both found by the project's pulse detector
(:func:`impactometer.signals.pulses.detect_pulses`, :func:`~impactometer.signals.stage_b.sustained_start`) with
the same detection levels on both.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError, ParameterTypeError, RecordingError, shown
from ..identify.model_fit.engine import Observed, Residuals, fit_law, staged, window
from ..identify.model_fit.forward import make_layout
from ..recording import Recording
from ..rig import Rig, get_rig
from ..signals.pulses import detect_pulses
from ..signals.stage_b import sustained_start
from .drops import _ObservedDrop, _read_drops
from .result import Drop

#: window after the start contact instant fitted first [s] (the contact instant is found on the first pulse)
FIRST_WINDOW = 0.004
#: a drop counts as reproduced when the share of its force NRMSE the noise does not explain (the two added in
#: quadrature) is at most this [-]: the held-back target of a calibrated stand (median force NRMSE 3 %)
REPRODUCED_LIMIT = 0.03


@dataclass(frozen=True, kw_only=True)
class DropValidation(Drop):
    """One held-back drop reproduced by a stand (V0 the light gate's; see the module notes for the figures)."""

    force_nrmse: float
    noise_nrmse: float
    peak_force_error: float
    first_pulse_error: float | None
    stage_b_error: float | None
    model_error_limit: float

    @property
    def model_error(self) -> float:
        """The share of the force NRMSE the noise does not explain (in quadrature) [-]."""
        return _model_error(self.force_nrmse, self.noise_nrmse)

    @property
    def reproduced(self) -> bool:
        """Whether the stand reproduces the drop: :attr:`model_error` at most ``model_error_limit``."""
        return self.model_error <= self.model_error_limit

    def verdict(self) -> str:
        """The verdict in words, with its threshold."""
        word = "reproduced" if self.reproduced else "not reproduced"
        sign = "<=" if self.reproduced else ">"
        return (f"{word}: force error beyond the noise {self.model_error:.2%} {sign} {self.model_error_limit:.0%} "
                "of the force range")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping (without the arrays)."""
        return {**super().to_dict(), "force_nrmse": self.force_nrmse, "noise_nrmse": self.noise_nrmse,
                "model_error": self.model_error, "model_error_limit": self.model_error_limit,
                "reproduced": self.reproduced, "verdict": self.verdict(),
                "peak_force_error": self.peak_force_error, "first_pulse_error_s": self.first_pulse_error,
                "stage_b_error_s": self.stage_b_error}


@dataclass(frozen=True, kw_only=True)
class Validation:
    """Held-back drops reproduced by a stand: ``drops`` and the median force NRMSE [-]."""

    stand: str
    contact_law: str
    drops: tuple[DropValidation, ...]

    @property
    def median_force_nrmse(self) -> float:
        """Median of the drops' force NRMSE [-]."""
        return float(np.median([d.force_nrmse for d in self.drops]))

    @property
    def reproduced(self) -> int:
        """Number of drops the stand reproduces (see :attr:`DropValidation.reproduced`)."""
        return sum(d.reproduced for d in self.drops)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping."""
        return {"stand": self.stand, "contact_law": self.contact_law, "median_force_nrmse": self.median_force_nrmse,
                "reproduced": self.reproduced, "drops": [d.to_dict() for d in self.drops]}

    def plot(self, folder: str | Path) -> list[Path]:
        """One figure per drop, measured and simulated channels with residuals, written to ``folder``."""
        from ..plotting.calibration import plot_drops

        return plot_drops(self.drops, folder, prefix="validate")


def _timing(measured: np.ndarray, simulated: np.ndarray, noise: float, rate: float):
    """(first-pulse end, stage-B start) errors, simulated − measured [s], each None where either lacks it."""
    scale = float(np.max(np.abs(measured)))
    spans = [detect_pulses(f, noise, force_scale=scale) for f in (measured, simulated)]
    first = None
    if all(s and s[0].complete for s in spans):
        first = (spans[1][0].end - spans[0][0].end) / rate
    starts = [sustained_start(s, size=measured.size) for s in spans]
    stage_b = None if None in starts else (starts[1] - starts[0]) / rate  # type: ignore[operator]
    return first, stage_b


def _force_nrmse(data: Observed, simulated: np.ndarray, contact_time: float) -> tuple[float, float]:
    """The force NRMSE of a drop, RMS(measured − simulated contact force) / (max − min of the measured force)
    from ``contact_time`` [s] to the end of ``data`` [-], and the share of it the noise alone gives (the
    pre-trigger σ over the same range) [-]; ``simulated`` (2, n) as ``data.channels``."""
    rate = data.grid.sample_rate
    onset = max(0, int(math.floor((contact_time - data.grid.start_time) * rate)))
    force = data.channels[0, onset:]
    span = float(np.max(force) - np.min(force)) or 1.0
    return float(np.sqrt(np.mean((force - simulated[0, onset:]) ** 2)) / span), float(data.noise[0] / span)


def _model_error(nrmse: float, noise: float) -> float:
    """The share of a force NRMSE the noise does not explain, the two added in quadrature [-]."""
    return math.sqrt(max(nrmse ** 2 - noise ** 2, 0.0))


def _validate_drop(drop: _ObservedDrop, rig: Rig) -> DropValidation:
    """One drop reproduced by ``rig`` (its own contact law), V0 held at the light gate's."""
    layout = make_layout(rig, rig.contact.law, (), pressure_gauge=drop.pressure_gauge, contact_time=drop.contact_time,
                         sample_rate=drop.data.grid.sample_rate, mass=drop.mass, velocity=drop.velocity)
    data = drop.data

    def fit_one(end, state):  # the first window finds the contact instant, the whole record the offsets
        values, offsets, _ = state
        part = data if end is None else window(data, drop.contact_time + end)
        fit = fit_law(part, layout, values, offsets=offsets, information=False)
        return fit.values, fit.offsets, fit

    _, _, fit = staged((FIRST_WINDOW, None), fit_one, ({"contact_time": drop.contact_time}, data.offsets, None))
    simulated = Residuals(data, layout).predicted(fit.x)
    rate = data.grid.sample_rate
    onset = max(0, int(math.floor((fit.values["contact_time"] - data.grid.start_time) * rate)))
    force = data.channels[0, onset:] - fit.offsets[0]
    model = simulated[0, onset:] - fit.offsets[0]
    nrmse, noise = _force_nrmse(data, simulated, fit.values["contact_time"])
    first_pulse, stage_b = _timing(force, model, float(data.noise[0]), rate)
    return DropValidation(source=drop.source, mass=drop.mass, velocity=drop.velocity,
                          pressure_gauge=drop.pressure_gauge,
                          force_nrmse=nrmse, noise_nrmse=noise, model_error_limit=REPRODUCED_LIMIT,
                          peak_force_error=float((np.max(model) - np.max(force)) / np.max(force)),
                          first_pulse_error=first_pulse, stage_b_error=stage_b, reduced_chi2=fit.reduced_chi2,
                          time=data.grid.start_time + np.arange(data.grid.size) / rate, measured=data.channels,
                          simulated=simulated)


def validate(rig: Rig | str | Path, recordings: Sequence[Recording]) -> Validation:
    """Reproduce held-back drops with the stand ``rig`` (a Rig, a preset name or a TOML file, e.g. a calibrated
    one) and report how well (see the module notes).

    Raises
    ------
    ParameterError
        For a stand that does not load, or none given (None is refused: the stand is named).
    RecordingError
        For a drop without its truth, drops of different stands, a recording the model cannot use.
    IdentificationError
        When a drop cannot be reproduced at all (the model cannot be integrated at its impact).
    """
    if rig is None:
        raise ParameterError("rig must name the stand to validate (a Rig, a preset name or a .toml file), got None; "
                             "the built-in stand is validated only when named ('drop-stand')", field="rig",
                             expected="must name the stand to validate")
    stand = get_rig(rig)
    if not isinstance(recordings, Sequence) or isinstance(recordings, (str, bytes)):
        raise ParameterTypeError(f"recordings must be a sequence of Recording, got {shown(recordings)}",
                                 field="recordings", expected="must be a sequence of Recording")
    if not recordings:
        raise RecordingError("recordings must hold at least one drop to validate the stand on, got none",
                             field="recordings", expected="must hold at least one drop")
    drops = _read_drops(recordings)
    return Validation(stand=stand.name, contact_law=stand.contact.law,
                      drops=tuple(_validate_drop(drop, stand) for drop in drops))
