"""Every layout of the compiled control loop's vectors, named: one layout per vector, packed at one boundary.

The compiled kernels (:mod:`.estimator`, :mod:`.windows`, :mod:`.controller`, :mod:`.plant`) keep their state in
flat float vectors, which numba handles fastest; the slots of each are written here as the members of an
``IntEnum`` and kept as a named tuple of plain ints (:func:`slots`), which every numba version reads as integer
constants (numba 0.60-0.62 cannot index an array with an ``IntEnum`` member). A vector is filled from the Python
objects it describes in one function (:func:`pack_settings`, :func:`pack_drive`) and read back by name with
:func:`unpack`; no other code builds one slot by slot.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import fields
from enum import IntEnum
from typing import TYPE_CHECKING, Any

import numpy as np

from ..model.actuated import ROUTES

if TYPE_CHECKING:
    from .valve import ValveDrive


def slots(layout: type[IntEnum]) -> Any:
    """The members of ``layout`` as a named tuple of plain ints with the same names (a class decorator): read by
    name (``Estimator.MASS``), counted (``len``), iterated in order, and a compile-time constant in the kernels."""
    make: Any = namedtuple  # a type made at run time, from the enum's names
    return make(layout.__name__, [member.name for member in layout])(*[int(member) for member in layout])


def names(layout: Any) -> tuple[str, ...]:
    """The slot names of ``layout`` (one of this module's), in order."""
    return tuple(layout._fields)


@slots
class Strategy(IntEnum):
    """Code of each strategy of the compiled controller (``ControlSettings.strategy``)."""

    CLOSED = 0
    CONSTANT = 1
    REALTIME = 2
    PREDICTIVE = 3
    LEVEL = 4


@slots
class Settings(IntEnum):
    """Slots of the packed :class:`~.settings.ControlSettings`: one per field, named after it, in field order."""

    STRATEGY = 0
    START = 1
    OPENING = 2
    MASS = 3
    MASS_STD = 4
    VELOCITY = 5
    USABLE_STROKE = 6
    TAU_CONTROL = 7
    TAU_FILTER = 8
    PRESSURE_LOWER_START = 9
    TEMPERATURE_LOWER_START = 10
    CLOSE_ON_STOP = 11
    MAX_FORCE = 12
    BOUNCE_GATE = 13
    BOUNCE_THRESHOLD = 14
    REFINE_MASS = 15
    FORCE_LEVEL = 16
    FORCE_NOISE = 17
    SUPERVISE = 18
    OBSERVER_BANDWIDTH = 19
    ACCELERATION_NOISE = 20
    EARLY_START = 21
    EARLY_MASS = 22
    EARLY_MASS_STD = 23
    EARLY_VELOCITY = 24
    MASS_FLOOR = 25


@slots
class Drive(IntEnum):
    """Slots of the drive vector: the valve actuator as its data sheet describes it (:class:`~.valve.ValveDrive`)."""

    #: dead time [s]
    DEAD_TIME = 0
    #: time constant of the first-order lag [s]
    TIME_CONSTANT = 1
    #: largest opening rate [1/s]
    MAX_RATE = 2
    #: discharge route (``model.actuated.ROUTES``)
    ROUTE = 3


@slots
class Estimator(IntEnum):
    """Slots of the estimator's state (:mod:`.estimator`); the stage-B windows' state (:class:`Windows`) follows
    from slot ``WINDOWS`` on."""

    IMPULSE = 0
    FORCE_PREV = 1
    P_LOWER_F = 2
    P_UPPER_F = 3
    X_HAT = 4
    V_HAT = 5
    ABOVE = 6
    BELOW = 7
    IN_CONTACT = 8
    CONTACT_START = 9
    FIRST_PULSE = 10
    MASS = 11
    MASS_STD = 12
    VELOCITY = 13
    SUSTAINED = 14
    LATCHED = 15
    OPENING_MODEL = 16
    TARGET = 17
    V_SLOW = 18
    STAGE_B = 19
    WINDOWS = 20


@slots
class Sums(IntEnum):
    """Offsets of the running sums from first contact on, wherever a copy of them is kept (the running ones, each
    sample of the sums ring, each stored end)."""

    #: Σ Fc [N·samples]
    FORCE = 0
    #: Σ (g − a2) [m/s²·samples]
    SHARED = 1
    #: samples
    SAMPLES = 2


#: running sums kept per copy
N_SUMS = len(Sums)
#: samples held by the rings of force and running sums
RING = 256
#: ends stored; when full, the last slot holds the newest end (the others remain candidates for the first)
MAX_ENDS = 256


@slots
class End(IntEnum):
    """Offsets within a stored end of the windows: the running sums there (:class:`Sums`), then these."""

    #: Fc there [N]
    FORCE_AT = N_SUMS
    #: g − a2 there [m/s²]
    SHARED_AT = N_SUMS + 1
    #: the timing's standard error [samples]
    TIMING = N_SUMS + 2


#: slots per stored end
END_SLOTS = N_SUMS + len(End)


@slots
class Windows(IntEnum):
    """Slots of the stage-B windows' state (:mod:`.windows`): scalars, then the start of each region."""

    LOOKING = 0
    EXTREME = 1
    EXTREME_AT = 2
    COUNT = 3
    OPENED = 4
    LAST_COMMIT = 5
    N_ENDS = 6
    MASS = 7
    STD = 8
    BEYOND = 9
    #: the running sums (:class:`Sums`)
    RUNNING = 10
    #: ring of the last RING samples' force
    FORCE_RING = RUNNING + N_SUMS
    #: ring of the last RING samples' running sums (N_SUMS per sample)
    SUMS_RING = FORCE_RING + RING
    #: the stored ends (END_SLOTS per end, :class:`End`)
    ENDS = SUMS_RING + RING * N_SUMS


#: length of the windows' state
N_WINDOWS = Windows.ENDS + MAX_ENDS * END_SLOTS
#: length of the estimator's state
N_ESTIMATOR = Estimator.WINDOWS + N_WINDOWS


def pack_settings(settings: Any) -> np.ndarray:
    """The settings (a :class:`~.settings.ControlSettings`, which packs itself through this function) as the vector
    the compiled loop reads (:class:`Settings`; the strategy as its :class:`Strategy` code)."""
    out = np.empty(len(Settings))
    for f in fields(settings):
        value = getattr(settings, f.name)
        code = getattr(Strategy, value.upper()) if f.name == "strategy" else float(value)
        out[getattr(Settings, f.name.upper())] = code
    return out


def pack_drive(drive: ValveDrive) -> np.ndarray:
    """The drive vector of the compiled loop (:class:`Drive`) for ``drive``."""
    out = np.empty(len(Drive))
    out[Drive.DEAD_TIME] = drive.dead_time
    out[Drive.TIME_CONSTANT] = drive.time_constant
    out[Drive.MAX_RATE] = drive.max_rate
    out[Drive.ROUTE] = ROUTES[drive.route]
    return out


def unpack(layout: Any, vector: np.ndarray) -> dict[str, float]:
    """The named slots of ``layout`` (one of this module's) in ``vector`` (a packed vector or a kernel's state), by
    lower-case name."""
    return {name.lower(): float(vector[index]) for name, index in layout._asdict().items()}
