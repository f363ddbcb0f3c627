"""The absorber's one reference force: the constant contact force that stops the mass within a given travel.

F0 of an impact (V0 over the usable stroke, :func:`impactometer.control.event.impact_force`), F_ref of a window
(:mod:`.metrics`), the controller's force target (:mod:`.controller`) and the rated-force check of
:func:`impactometer.control.absorb` are all this force.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, error_model="numpy")
def stopping_force(mass, velocity, remaining, gravity):
    """M1·(v²/(2·s) + g) [N]: the constant contact force that stops a mass M1 [kg] moving down at ``velocity``
    [m/s] within ``remaining`` [m] of travel, against gravity ``gravity`` [m/s²]."""
    return mass * (velocity * velocity / (2.0 * remaining) + gravity)
