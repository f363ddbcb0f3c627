"""The drop-stand model with valve Z driven by an actuator: the model state plus the valve opening.

The opening is the fraction of the fully open valve [-] (0 closed, 1 open), an extra state that follows the command
held in the input vector ``u`` through a first-order lag with an optional rate limit. The flow law is the stand's
(:func:`.dynamics.valve_mass_flow`, orifice or ISO 6358) at the area ``opening · max_area``. The valve discharges the
lower chamber into the upper one (the stand of the reference paper) or to atmosphere. With the valve closed the
right-hand side is exactly :func:`.dynamics.rhs` with a zero opening. A dead time of the actuator is a delay of the
command; the controlled loop applies it (``control.plant``).
"""

from __future__ import annotations

from numba import njit

from . import dynamics as d

#: index of the valve opening in the actuated state
OPENING = d.N_STATE
N_STATE = d.N_STATE + 1
#: input vector: commanded opening [-], lag time constant [s], largest opening rate [1/s], discharge route
COMMAND, TIME_CONSTANT, MAX_RATE, ROUTE = range(4)
N_INPUT = 4
#: discharge routes of the lower chamber
TO_UPPER, TO_ATMOSPHERE = 0, 1
ROUTES = {"upper": TO_UPPER, "atmosphere": TO_ATMOSPHERE}


@njit(cache=True, error_model="numpy")
def derivatives(y, p, u, dy):
    """Time derivative of the actuated state ``y`` (model state + opening) for the inputs ``u`` (not named ``rhs``:
    the GPU build (:mod:`.gpu`) rebinds compiled functions by name, and ``d.rhs`` inside a function named ``rhs``
    would name the function itself)."""
    opening = min(max(y[OPENING], 0.0), 1.0)
    area = opening * p[d.VALVE_MAX_AREA]
    if u[ROUTE] == TO_UPPER:
        d.rhs(y, p, area, dy)
    else:  # the lower chamber vents to atmosphere: the model's closed cylinder plus an outflow
        d.rhs(y, p, 0.0, dy)
        if area > 0.0 and y[d.P_LOWER] > p[d.ATMOSPHERE]:
            vol_lower, _ = d.volumes(y[d.U2], p)
            t_lower = y[d.P_LOWER] * vol_lower / (y[d.M_LOWER] * p[d.GAS_CONSTANT])
            mdot = d.valve_mass_flow(y[d.P_LOWER], t_lower, p[d.ATMOSPHERE], area, p)
            dy[d.P_LOWER] -= p[d.GAMMA] * p[d.GAS_CONSTANT] * t_lower * mdot / vol_lower
            dy[d.M_LOWER] -= mdot
    rate = (u[COMMAND] - y[OPENING]) / u[TIME_CONSTANT]
    dy[OPENING] = max(-u[MAX_RATE], min(u[MAX_RATE], rate))
