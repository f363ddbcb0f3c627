"""The closed loop of the controlled stand: sensors → estimator → controller → actuator → model.

The plant is the drop-stand model with valve Z and its actuator (:mod:`impactometer.model.actuated`: the opening is
one more state). A digital controller runs at every sample instant: it reads the sensors (the model's channels plus
sensor noise), updates its estimates (:mod:`.estimator`) and sends an opening command (:mod:`.controller`). The
actuator receives each command after its dead time and holds it until the next one (zero-order hold); between
samples, and at the instant a delayed command arrives, the state is integrated by the package's one Dormand-Prince
stepper (:mod:`impactometer.model.stepper`), restarted there because the input jumps. With the valve closed the
plant is exactly the closed-cylinder model.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from ..errors import ParameterError, SimulationError
from ..model import actuated, dynamics, stepper
from ..model.setup import initial_state, pack
from ..model.simulate import absolute_tolerance, sample_times, simulation_result
from ..rig import Rig, Scenario, get_rig
from ..validation import check_real
from . import controller, estimator
from .settings import ControlSettings
from .state import Drive, Estimator, Settings, pack_drive
from .valve import ValveDrive

#: the sensors the controller reads (model channels), in the order of the rows of the noise matrix
SENSOR_CHANNELS = ("contact_force", "a2", "pressure_lower", "pressure_upper", "u2")
SENSOR_INDEX = np.array([dynamics.CHANNELS.index(name) for name in SENSOR_CHANNELS])
N_SENSOR = len(SENSOR_CHANNELS)
#: controller histories returned next to the model's
HISTORIES = ("valve_opening", "valve_command", "target_force", "estimated_velocity", "estimated_piston_displacement",
             "estimated_mass", "estimated_mass_std", "sustained_contact")
#: largest number of integration steps between two samples
MAX_STEPS_PER_SAMPLE = 100_000
#: a failed run whose piston is beyond this fraction of the stroke ended at the bottom stop
BOTTOM_FRACTION = 0.95


@njit(cache=True, error_model="numpy")
def _advance(y, p, u, interval, h, rtol, atol, k):
    return stepper.advance(stepper.ACTUATED, y, p, u, interval, h, rtol, atol, math.inf, MAX_STEPS_PER_SAMPLE, k)


@njit(cache=True, error_model="numpy")
def run_loop(p, y0, ctrl, drive, noise, sample_rate, rtol, atol, out, extra, stop_after, program):
    """Closed-loop simulation sampled at ``sample_rate`` [Hz] for ``out.shape[1]`` samples.

    ``noise`` (N_SENSOR, n) is added to the sensors the controller reads; ``out`` (N_CHANNEL, n) receives the
    model channels and ``extra`` (len(HISTORIES), n) the controller's histories. The run ends early, ``stop_after``
    [s] after the mass, in contact, turned back up (its deepest point) once the control has started (``inf``:
    never). ``program`` (n commands [-], or empty) replaces the controller's commands by a fixed opening program
    (the estimator still runs). Returns a status code of the stepper and the index of the last sample written.
    """
    n = out.shape[1]
    dt = 1.0 / sample_rate
    y = np.empty(actuated.N_STATE)
    y[:dynamics.N_STATE] = y0
    y[actuated.OPENING] = 0.0
    k = np.empty((stepper.WORK_ROWS, actuated.N_STATE))
    u = np.zeros(actuated.N_INPUT)
    u[actuated.TIME_CONSTANT] = drive[Drive.TIME_CONSTANT]
    u[actuated.MAX_RATE] = drive[Drive.MAX_RATE]
    u[actuated.ROUTE] = drive[Drive.ROUTE]
    lag = drive[Drive.DEAD_TIME] / dt  # dead time in samples: whole part and fraction
    whole = int(math.floor(lag + 1e-9))
    fraction = lag - whole if lag - whole > 1e-9 else 0.0
    size = whole + 2
    history = np.zeros(size)  # commands sent, by sample index modulo size (unsent ones read as closed)
    predicted_delay = int(round(lag))
    e = estimator.initial(y0, ctrl)
    row = np.empty(dynamics.N_CHANNEL)
    h = dt
    turned = math.inf
    for j in range(n):
        t = j * dt
        if t > turned + stop_after:
            return stepper.OK, j - 1
        dynamics.channels(y, p, row)
        if turned == math.inf and t > min(ctrl[Settings.START], ctrl[Settings.EARLY_START]) \
                and y[dynamics.V1] < 0.0 and row[SENSOR_INDEX[0]] > 0.0:
            turned = t  # the mass, in contact, turns back up: its deepest point
        for i in range(dynamics.N_CHANNEL):
            out[i, j] = row[i]
        estimator.update(e, t, dt, row[SENSOR_INDEX[0]] + noise[0, j], row[SENSOR_INDEX[1]] + noise[1, j],
                         row[SENSOR_INDEX[2]] + noise[2, j], row[SENSOR_INDEX[3]] + noise[3, j],
                         row[SENSOR_INDEX[4]] + noise[4, j], p[dynamics.GRAVITY], ctrl)
        command = controller.command_of(t, dt, p, ctrl, drive, e, history, (j - 1) % size, predicted_delay)
        if program.size:
            command = program[j]
        history[j % size] = command
        extra[0, j] = y[actuated.OPENING]
        extra[1, j] = command
        extra[2, j] = e[Estimator.TARGET]
        extra[3, j] = e[Estimator.VELOCITY]
        extra[4, j] = e[Estimator.X_HAT]
        extra[5, j] = e[Estimator.MASS]
        extra[6, j] = e[Estimator.MASS_STD]
        extra[7, j] = e[Estimator.SUSTAINED]
        # the controller's model of the opening, driven by the command that acts now
        sent = history[(j - predicted_delay) % size]
        e[Estimator.OPENING_MODEL] = controller.actuator_step(e[Estimator.OPENING_MODEL], sent, dt, drive)
        if j == n - 1:
            break
        if fraction > 0.0:  # the command sent whole + 1 samples ago acts until the next one arrives
            u[actuated.COMMAND] = history[(j - whole - 1) % size]
            status, h, _ = _advance(y, p, u, fraction * dt, h, rtol, atol, k)
            if status != stepper.OK:
                return status, j
        u[actuated.COMMAND] = history[(j - whole) % size]
        status, h, _ = _advance(y, p, u, (1.0 - fraction) * dt, h, rtol, atol, k)
        if status != stepper.OK:
            return status, j
    return stepper.OK, n - 1


def simulate_controlled(scenario: Scenario, rig: Rig | str | None = None, *, control: ControlSettings | None = None,
                        drive: ValveDrive | None = None, duration: float = 0.3, sample_rate: float = 50e3,
                        sensor_noise: np.ndarray | None = None, rtol: float = 1e-7, stop_after: float = math.inf,
                        program: np.ndarray | None = None):
    """Simulate one drop test with valve Z driven by a controller.

    Parameters
    ----------
    scenario : Scenario
        The impact (true M1 [kg], V0 [m/s], p0 [Pa gauge]).
    rig : Rig or str, optional
        The stand (default ``drop-stand``); ``rig.valve`` gives the flow law and the fully open valve (its constant
        ``area`` is ignored).
    control : ControlSettings, optional
        The controller (default: valve closed throughout).
    drive : ValveDrive, optional
        Valve actuator (default ``ValveDrive()``).
    duration, sample_rate : float
        Simulated time after first contact [s] and the controller/sensor rate [Hz].
    sensor_noise : ndarray, optional
        Noise (N_SENSOR, n_samples) added to the sensors the controller reads, rows in the order of
        ``SENSOR_CHANNELS`` [N, m/s², Pa, Pa, m].
    rtol : float
        Relative tolerance of the integrator.
    stop_after : float
        End the run this long after the mass's deepest point once the control has started [s] (``inf``: at
        ``duration``); the histories are then shorter.
    program : ndarray, optional
        An opening program: the valve command [-] at every sample (within [0, 1]) in place of the controller's;
        the actuator's dead time and lag still apply.

    Returns
    -------
    (SimulationResult, dict)
        The model histories and the controller's (``HISTORIES``): ``valve_opening`` and ``valve_command`` [-],
        ``target_force`` [N], ``estimated_velocity`` (mass) [m/s], ``estimated_piston_displacement`` [m],
        ``estimated_mass`` and ``estimated_mass_std`` [kg], ``sustained_contact`` (1 in stage B as detected).
    """
    if not isinstance(scenario, Scenario):
        raise ParameterError(f"scenario must be a Scenario, got {scenario!r}")
    rig = get_rig(rig)
    drive = ValveDrive() if drive is None else drive
    control = ControlSettings() if control is None else control
    if not isinstance(control, ControlSettings):
        raise ParameterError(f"control must be a ControlSettings, got {control!r}")
    if not isinstance(drive, ValveDrive):
        raise ParameterError(f"drive must be a ValveDrive, got {drive!r}")
    rtol = check_real("rtol", rtol, low=1e-13, high=1e-3, state_range=True)
    t = sample_times(duration, sample_rate)
    p = pack(rig, scenario)
    p[dynamics.VALVE_AREA] = 0.0
    y0 = initial_state(p)
    noise = np.zeros((N_SENSOR, t.size)) if sensor_noise is None else np.ascontiguousarray(sensor_noise, float)
    if noise.shape != (N_SENSOR, t.size):
        raise ParameterError(f"sensor_noise must have shape {(N_SENSOR, t.size)}, got {noise.shape}")
    atol = np.append(absolute_tolerance(rtol), rtol * 1e-3)  # the opening: a fraction of the open valve
    chans = np.empty((dynamics.N_CHANNEL, t.size))
    extra = np.empty((len(HISTORIES), t.size))
    stop_after = check_real("stop_after", stop_after, low=0.0, finite=False, unit=" [s] (inf: never)",
                            state_range=True)
    commands = np.zeros(0) if program is None else np.ascontiguousarray(program, float)
    if program is not None and (commands.shape != t.shape or not np.all((commands >= 0.0) & (commands <= 1.0))):
        raise ParameterError(f"program must hold {t.size} commands within [0, 1], got shape {commands.shape}")
    status, last = run_loop(p, y0, control.packed(), pack_drive(drive), noise, float(sample_rate), rtol, atol,
                            chans, extra, stop_after, commands)
    note = {}
    if status == stepper.OK and last < t.size - 1:
        t, chans, extra = t[:last + 1], chans[:, :last + 1], extra[:, :last + 1]
    if status != stepper.OK:
        if chans[dynamics.CHANNELS.index("u2"), last] < BOTTOM_FRACTION * rig.cylinder.stroke:
            raise SimulationError(f"controlled simulation failed ({stepper.STATUS_TEXT[status]}) at "
                                  f"t = {t[last]:.6f} s for {scenario}")
        # the piston reached the bottom with the lower chamber emptied through the valve: the run ends there
        note = {"ended_at_bottom": float(t[last])}
        t, chans, extra = t[:last + 1], chans[:, :last + 1], extra[:, :last + 1]
    result = simulation_result(t, chans, p, y0, rig, scenario, "controlled")
    return dataclasses.replace(result, extra=note), dict(zip(HISTORIES, extra, strict=True))
