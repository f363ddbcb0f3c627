"""Reference integrator: scipy ``solve_ivp`` with tight tolerances on the same model equations."""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import SimulationError
from . import dynamics as d


def integrate(p: np.ndarray, y0: np.ndarray, t_out: np.ndarray, *, rtol: float = 1e-10,
              atol: np.ndarray, method: str = "DOP853", max_step: float = np.inf) -> np.ndarray:
    """States at ``t_out`` (shape (N_STATE, len(t_out))) integrated by ``solve_ivp``.

    Raises
    ------
    SimulationError
        If the solver does not reach the end time.
    """
    valve = float(p[d.VALVE_AREA])

    def fun(_t, y):
        dy = np.empty_like(y)
        d.rhs(y, p, valve, dy)
        return dy

    sol = solve_ivp(fun, (0.0, float(t_out[-1])), y0, method=method, t_eval=t_out, rtol=rtol, atol=atol,
                    max_step=max_step)
    if sol.status != 0 or sol.y.shape[1] != t_out.size:
        raise SimulationError(f"reference integrator ({method}) failed: {sol.message}")
    return sol.y


def channels_of(states: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Every channel (shape (N_CHANNEL, n)) for states of shape (N_STATE, n)."""
    out = np.empty((d.N_CHANNEL, states.shape[1]))
    row = np.empty(d.N_CHANNEL)
    for i in range(states.shape[1]):
        d.channels(np.ascontiguousarray(states[:, i]), p, row)
        out[:, i] = row
    return out
