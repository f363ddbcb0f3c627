"""The paper's peak-to-peak method as published: eqs. (3)-(5) read at the force peaks of the first two pulses."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...errors import IdentificationError
from ..result import Identification
from .robust import Kinematics
from .segment import Segment, check_velocity, need_pulses, second_peak, segment_onset


def solve_paper(seg: Segment, gravity: float, early=None) -> Identification:
    """Eqs. (3)-(5) of the reference paper and the momentum step for V0.

    t00 = first contact, t01/t11 = force peaks of the first two pulses; M1 = −∫Fc / ((V2(t11) − V2(t01)) −
    g·Δt) (eq. 4), V2 = ∫a2 from t00 (eq. 5), V0 = V2(t01) + ∫_{t00}^{t01}Fc/M1 − g·(t01 − t00).
    """
    peak2 = second_peak(seg)
    if peak2 is None:
        need_pulses(seg, 2, "the paper variant")
        raise IdentificationError("the paper variant needs the second force peak: the second pulse has not yet "
                                  "fallen from a maximum")
    p1 = seg.pulses[0]
    t00, _ = segment_onset(seg, p1)
    kin = Kinematics(seg.force, seg.acceleration, 1.0 / seg.sample_rate, t00, gravity)
    tau, _, jf, _, _, va, _ = kin.at(np.array([p1.peak, peak2], dtype=float))
    denominator = (va[1] - va[0]) - gravity * (tau[1] - tau[0])
    impulse = jf[1] - jf[0]
    if not denominator < 0.0 or impulse <= 0.0:
        raise IdentificationError(f"the paper's eq. (4) has no positive mass here: ∫Fc = {impulse:.4g} N·s, "
                                  f"ΔV2 − gΔt = {denominator:.4g} m/s (expected < 0)")
    mass = -impulse / denominator
    velocity = va[0] + jf[0] / mass - gravity * tau[0]
    check_velocity(velocity, "the paper's eqs. (3)-(5)")
    details: dict[str, Any] = {"t00": seg.time_of(t00), "t01": seg.time_of(p1.peak), "t11": seg.time_of(peak2),
                               "onsets": (), "noise_force_N": seg.noise_force,
                               "noise_acceleration_m_s2": seg.noise_acceleration}
    caution = paper_caution(seg)
    if caution:
        details["caution"] = caution
    return Identification(mass=float(mass), velocity=float(velocity), available_at=seg.time_of(peak2),
                          method="peak-to-peak/paper", details=details)


#: noise, as a fraction of a channel's peak, above which the paper variant's answer carries a caution [-]
PAPER_NOISE_LIMIT = 0.002


def paper_caution(seg: Segment) -> str | None:
    """A caution when the paper's assumption of noise-free channels is visibly violated, else None."""
    force = seg.noise_force / max(float(np.max(np.abs(seg.force))), 1e-300)
    acceleration = seg.noise_acceleration / max(float(np.max(np.abs(seg.acceleration))), 1e-300)
    if max(force, acceleration) <= PAPER_NOISE_LIMIT:
        return None
    return (f"eqs. (3)-(5) read single samples at the force peaks and assume noise-free channels; here the noise "
            f"is {force:.1%} of the peak force and {acceleration:.1%} of the peak acceleration, so this answer "
            "may be far off (the robust variant accounts for the noise)")
