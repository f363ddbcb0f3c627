"""Robust peak-to-peak identification: every equation the record holds, one generalised least-squares estimate.

Axis down, t measured from first contact t00. The mass obeys M1·ü1 = M1·g − Fc, the piston's acceleration a2 is
measured, so the relative displacement (overlap) of mass and rod and its rates are

    δ(t) = V0·τ + (g + b)·τ²/2 − w·IF(t) − D2(t),    δ'(t) = V0 + (g + b)·τ − w·JF(t) − V2(t),
    δ''(t) = g + b − w·Fc(t) − a2(t),

τ = t − t00, w = 1/M1, JF/IF the single/double integrals of the force and V2/D2 those of the acceleration from t00
(the piston at rest before contact), b the offset left in the channels after the pre-trigger correction. The
equations, all linear in (V0, w, b):

- onset k (a pulse starts): δ(Tk) = 0 -- whatever the contact law, the force is positive only while the bodies
  overlap (a pulse starts from a fresh contact);
- force extremum k (a peak of a bounce, or a peak or trough of the force in sustained contact, stage B):
  δ'(Ek) + λe·δ''(Ek) = 0 -- the force turns where the overlap turns (exactly for an elastic or hysteretic law,
  with the lag λe = c/k for a viscous one). In stage B consecutive extrema are the exact integral of
  M1·(g − a2) = Fc over the samples between them: the mass and the rod share one acceleration on average over
  every half-cycle of the contact's own oscillation, whatever the law;
- separation k (a pulse ends): δ(Sk) + λs·δ'(Sk) − μ·δ(Pk) = 0 -- the contact lets go ahead of zero overlap by a
  lag (viscous contact, λs = c/k) or at a fraction μ of the pulse's largest overlap δ(Pk) (a set, as a hysteretic
  pad takes one); 0 for a force that vanishes with the overlap.

The nuisances b (with its pre-trigger prior), λe, λs and μ are estimated with (V0, w). The covariance of the
rows is that of the double-integrated white noise of both channels (the kernels of
:func:`.covariance.atom_kernel`), of the times of the onsets, extrema and separations (rate × time error; the
error of t00 acts on every displacement alike), and, for the rows that rest on a model of the contact (extrema,
separations), a model-error variance estimated from their own scatter. It depends on the estimate, so the solution
is iterated (Gauss-Newton).
"""

from dataclasses import replace

import numpy as np

from ..details import GapReadings
from .gls import SET_MAX, Equations, Solution
from .gls import solve as _solve_rows
from .kinematics import Kinematics


def solve_rows(kin: Kinematics, eqs: Equations, *, noise_force: float, noise_acceleration: float,
               pre_samples: int, lag_max: float) -> Solution:
    """Generalised least squares for (V0, w) from the rows of ``eqs`` (module notes and :func:`.gls.solve`).

    Every gap is first taken for a flight. Where stage B has an estimate of its own, the gaps are also judged by
    that estimate first (a pad with a set may never let the mass fly), and of the two answers the one whose
    turning points and separations scatter less beyond their noise is kept -- unless that one needs a contact
    model at the edge of its range (a set or a lag at its bound) and the other, inside its range, scatters less
    than ``BOUNDED_SCATTER`` times as much. Where the flights are kept with onsets the other reading drops, and
    that reading fits as well, the difference of the two readings is added to the covariance: whether those gaps
    were flights is not in the data.
    """
    options: dict = dict(noise_force=noise_force, noise_acceleration=noise_acceleration, pre_samples=pre_samples,
                         lag_max=lag_max)
    flights = _solve_rows(kin, eqs, judge_by_stage_b=False, **options)
    if int(np.count_nonzero(eqs.stage_b)) < STAGE_B_ROWS or not eqs.onsets.size:
        return flights
    judged = _solve_rows(kin, eqs, judge_by_stage_b=True, **options)

    def bounded(sol: Solution) -> bool:
        found = sol.nuisances
        return any(value >= 0.99 * limit for value, limit in ((found.set_fraction, SET_MAX), (found.lag_e, lag_max),
                                                              (found.lag_s, lag_max)) if value is not None)

    # the one that scatters less wins, unless it needs a model at the edge of its range and the other, without
    # one, scatters within its noise or less than BOUNDED_SCATTER times as much
    best, other = (judged, flights) if judged.scatter < flights.scatter else (flights, judged)
    near = other.scatter <= max(1.0, BOUNDED_SCATTER * best.scatter)
    chosen = other if bounded(best) and not bounded(other) and near else best
    if chosen is flights and flights.used.onsets > judged.used.onsets \
            and judged.scatter <= max(1.0, flights.scatter):
        # the flights keep onsets the judged reading doubts, and the data fit both readings as well: whether those
        # gaps were flights (a pad that kept no set) is not in the data, so their difference is in the answer's σ
        diff = flights.theta - judged.theta
        readings = GapReadings(flights=(float(flights.theta[0]), 1.0 / float(flights.theta[1])),
                               kept_set=(float(judged.theta[0]), 1.0 / float(judged.theta[1])))
        chosen = replace(flights, cov=flights.cov + np.outer(diff, diff), readings=readings)
    return chosen

#: a model at the edge of its range (a set or a lag at its bound) is taken only where the other reading of the gaps
#: scatters this many times more beyond its noise (model-error variance over noise variance) [-]
BOUNDED_SCATTER = 4.0
#: turning points in stage B from which its own estimate judges the gaps before the onsets are used [-]: two
#: consecutive ones bound one window of M1·∫(g − a2) dt = ∫Fc dt, the least that gives stage B a mass of its own
STAGE_B_ROWS = 2
