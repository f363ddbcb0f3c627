"""The first answers of the model fit: M1 and V0 from the first milliseconds after first contact, window by window,
as a real-time system gets them.

With the stand known (a calibrated stand: its contact law and parameters, its seal friction, the charge pressure),
the first contact pulse alone carries M1 and V0: the rise of the force gives V0 within a few tenths of a per cent
after 3 ms, and its turn over and the piston's response give M1 (on the built-in pad stand at 2 % noise, the
Cramér-Rao σ of M1 is about 5-15 % of it after 3 ms, 0.3-4 % after 4 ms and 0.2-1 % after 6 ms). Each window fits
M1, V0, the contact instant and both sensor offsets by weighted least squares (:func:`.fit.fit_law`, the same
likelihood as the whole-record fit), started from the previous window's answer; the first window starts from the
impact of a grid (:func:`.select.grid_start`) whose prediction fits that window's data best. Nothing after the end
of a window is read for its answer.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace

from ...errors import IdentificationError, ParameterError, shown
from ...recording import Recording
from ...rig import Rig, get_rig
from ...sensors import anti_alias_delay
from ..result import Identification
from .fit import LawFit, Observed, fit_law, window
from .forward import make_layout
from .information import bound_of

#: most residual evaluations of one window's fit (from the last window's answer it converges in 3-10)
EARLY_EVALUATIONS = 30
#: end of the first window and the last end of a window after the trigger [s]
FIRST_WINDOW = 0.0025
LAST_WINDOW = 0.012
#: shortest step between the ends of two windows [s]
MIN_STEP = 2.5e-4
#: record before the trigger that the fits read [s] (the offsets start from the whole pre-trigger's median; more
#: of it would cost time in every prediction and hardly change M1 or V0)
LOOK_BACK = 0.002


@dataclass(frozen=True)
class EarlyFit:
    """The fit of the record up to ``end`` [s, on the recording's clock]: M1 [kg], V0 [m/s] and their standard
    errors (Fisher information, inflated by sqrt(χ²/dof) where that exceeds 1), χ²/dof, the time from the end of
    the data to the answer ``latency`` [s] (the fit's processor time on one core, or a fixed one) and the
    processor time of the grid start ``arming_time`` [s] (spent before the impact)."""

    end: float
    mass: float
    velocity: float
    mass_std: float
    velocity_std: float
    reduced_chi2: float
    contact_time: float
    latency: float
    arming_time: float
    law: str

    @property
    def available_at(self) -> float:
        """When the answer is known [s, on the recording's clock]."""
        return self.end + self.latency

    def answer(self) -> Identification:
        """This fit as the project's one result type (method ``model/early``)."""
        reason = (f"the {self.law} model of the stand fitted to the record up to {self.end * 1e3:.3g} ms "
                  f"(answer {self.latency * 1e3:.3g} ms later)")
        return Identification(mass=self.mass, velocity=self.velocity, mass_std=self.mass_std,
                              velocity_std=self.velocity_std, available_at=self.available_at, method="model/early",
                              details={"path": "early", "contact_law": self.law, "t00": self.contact_time,
                                       "reduced_chi2": self.reduced_chi2, "reason": reason})


def _from(data: Observed, start: float) -> Observed:
    """``data`` from the instant ``start`` [s] on the recording's clock (all of it when that is before its
    start)."""
    k = max(0, int(math.ceil((start - data.grid.start_time) * data.grid.sample_rate)))
    grid = data.grid
    return replace(data, channels=data.channels[:, k:],
                   grid=replace(grid, start_time=grid.start_time + k / grid.sample_rate, size=grid.size - k))


def _early_fit(fit: LawFit, end: float, latency: float, arming: float) -> EarlyFit:
    mass, velocity = fit.values["mass"], fit.values["velocity"]
    inflation = math.sqrt(max(1.0, fit.reduced_chi2))
    crb = bound_of(fit.cov, mass, velocity, law=fit.law, at="estimate", unknowns=("mass", "velocity"))
    return EarlyFit(end=end, mass=mass, velocity=velocity, mass_std=crb.mass_std * inflation,
                    velocity_std=crb.velocity_std * inflation, reduced_chi2=fit.reduced_chi2,
                    contact_time=fit.values["contact_time"], latency=latency, arming_time=arming,
                    law=fit.law)


def early_fits(recording: Recording, rig: Rig | str | None, *, pressure: float, first: float = FIRST_WINDOW,
               last: float = LAST_WINDOW, latency: float | None = None) -> Iterator[EarlyFit]:
    """Fit the stand model to the record from the trigger on, as a real-time system on one core would.

    The first fit reads the record up to ``first`` after the trigger; each next one starts when the last one is
    done and reads the record up to that instant (at least :data:`MIN_STEP` more), until ``last``. A fit's answer
    is known ``latency`` after the end of its data: the processor time the fit took (None) or a fixed time.
    The grid start is computed while the system waits for the impact (its predictions depend on the stand and the
    pre-charge only): its processor time is reported as ``EarlyFit.arming_time``, not counted in the latency.

    Parameters
    ----------
    recording : Recording
        Contact force [N] and piston acceleration [m/s²] with a pre-trigger (as :func:`.identify` needs).
    rig : Rig or str
        The stand, known: its contact law and parameters are held.
    pressure : float
        Charge pressure p0 [Pa gauge], known.
    first, last : float
        End of the first window and last end of a window after the trigger (the first sample of the force 10 σ
        off its pre-trigger) [s].
    latency : float, optional
        Fixed time from the end of a window's data to its answer [s] (reproducible runs); default: the fit's
        measured processor time.

    Yields
    ------
    EarlyFit
        One per window; a fit that fails ends the sequence with an IdentificationError.
    """
    from . import TRIGGER_LEAD, _check_length, _design, _observe
    from .select import grid_start

    rig = get_rig(rig)
    for name, value in (("first", first), ("last", last)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
            raise ParameterError(f"{name} must be a duration > 0 [s], got {shown(value)}")
    if last < first:
        raise ParameterError(f"last must be at least first = {first:g} s, got {shown(last)}")
    if latency is not None and not (isinstance(latency, (int, float)) and math.isfinite(latency) and latency >= 0):
        raise ParameterError(f"latency must be a duration >= 0 [s] or None (measured), got {shown(latency)}")
    if not (isinstance(pressure, (int, float)) and math.isfinite(pressure) and pressure >= 0.0):
        raise ParameterError(f"pressure must be a number >= 0 [Pa gauge], got {shown(pressure)}")
    design = _design(recording)
    trigger = _check_length(recording)
    data = _from(_observe(recording, design, trigger), trigger - LOOK_BACK)
    lead = anti_alias_delay(design, recording.sample_rate) + TRIGGER_LEAD / recording.sample_rate
    armed = time.process_time()
    start = grid_start(window(data, trigger + first), rig, trigger - lead, float(pressure), float(pressure))
    arming = time.process_time() - armed
    layout = make_layout(rig, rig.contact.law, (), pressure=float(pressure), contact_time=start.contact_time,
                         sample_rate=recording.sample_rate)
    values = {"mass": start.mass, "velocity": start.velocity, "contact_time": start.contact_time}
    end = first
    while end <= last:
        began = time.process_time()
        try:
            fit = fit_law(window(data, trigger + end), layout, values, evaluations=EARLY_EVALUATIONS)
        except IdentificationError as exc:
            raise IdentificationError(f"{recording.source}: the model fit of the first {end * 1e3:.3g} ms failed "
                                      f"({exc})") from None
        took = time.process_time() - began if latency is None else float(latency)
        values = {name: fit.values[name] for name in ("mass", "velocity", "contact_time")}
        yield _early_fit(fit, trigger + end, took, arming)
        end += max(took, MIN_STEP)
