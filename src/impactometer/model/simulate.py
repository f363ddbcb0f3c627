"""Public simulation API: one scenario (reference or fast integrator) or a batch (fast, parallel)."""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import ParameterError, SimulationError
from ..rig import Rig, Scenario, get_rig
from ..validation import check_integer, check_real
from . import dynamics as d
from . import fast, gpu, reference
from .result import BatchResult, SimulationResult
from .setup import initial_state, initial_states, pack, pack_batch

#: the integrators (their names) and the relative tolerance each runs at by default [-]
DEFAULT_RTOL = {"fast": 1e-9, "reference": 1e-10}
DEFAULT_BATCH_CHANNELS = ("contact_force", "a2")
#: default bound of the step size [s] (a contact pulse lasts milliseconds, so none is stepped over)
MAX_STEP = 1e-3
#: default bound of the number of accepted steps per scenario
MAX_STEPS = 10_000_000
_CHUNK_BYTES = 64 * 2**20
#: largest batch of histories simulate_batch holds in memory when the machine's memory is not known [bytes]
FALLBACK_BATCH_BYTES = 16 * 2**30


def memory_bytes() -> int:
    """Physical memory of this machine [bytes], or :data:`FALLBACK_BATCH_BYTES` where the system does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return FALLBACK_BATCH_BYTES
_STATE_SCALE = np.array([0.1, 1.0, 0.1, 1.0, 1e5, 1e5, 1e-3, 1e-4, 100.0, 1e-3])


def absolute_tolerance(rtol: float) -> np.ndarray:
    """Per-state absolute tolerance matching a relative tolerance ``rtol`` on the state's typical scale."""
    return rtol * _STATE_SCALE


def sample_times(duration: float, sample_rate: float) -> np.ndarray:
    """Sample instants 0, 1/fs, ... up to ``duration`` [s]."""
    check_real("duration", duration, low=0.0, low_open=True, unit=" [s]")
    check_real("sample_rate", sample_rate, low=0.0, low_open=True, unit=" [Hz]")
    product = duration * sample_rate
    if not product < 5e7:  # also an overflow to inf
        raise ParameterError(f"duration·sample_rate must give at most 5e7 samples, got {duration!r} s at "
                             f"{sample_rate!r} Hz")
    n = int(np.floor(product + 1e-9)) + 1
    if n < 2:
        raise ParameterError(f"duration·sample_rate must give at least 2 samples, got {duration!r} s at "
                             f"{sample_rate!r} Hz")
    return np.arange(n) / sample_rate


def _check_integrator(integrator: str, rtol: float | None, max_step: float = MAX_STEP,
                      max_steps: int = MAX_STEPS) -> float:
    if integrator not in DEFAULT_RTOL:
        raise ParameterError(f"integrator must be one of {sorted(DEFAULT_RTOL)}, got {integrator!r}")
    rtol = DEFAULT_RTOL[integrator] if rtol is None else rtol
    check_real("max_step", max_step, low=0.0, low_open=True, finite=False, unit=" [s] (inf for no bound)")
    check_integer("max_steps", max_steps, low=1)
    return check_real("rtol", rtol, low=1e-14, high=1e-3)


def simulate(scenario: Scenario, rig: Rig | None = None, *, duration: float = 0.05, sample_rate: float = 50e3,
             integrator: str = "fast", rtol: float | None = None, max_step: float = MAX_STEP,
             max_steps: int = MAX_STEPS) -> SimulationResult:
    """Simulate one drop test.

    Parameters
    ----------
    scenario : Scenario
        Impacting mass M1 [kg], impact velocity V0 [m/s], charge pressure p0 [Pa gauge].
    rig : Rig, optional
        The stand (default: the built-in ``drop-stand``).
    duration : float
        Simulated time after first contact [s].
    sample_rate : float
        Rate of the returned histories [Hz].
    integrator : {"fast", "reference"}
        Compiled Dormand-Prince 5(4) (scipy's RK45 algorithm) or scipy ``solve_ivp`` (DOP853).
    rtol : float, optional
        Relative tolerance (default 1e-9 fast, 1e-10 reference); the absolute tolerances are ``rtol`` times the
        typical scale of each state (0.1 m, 1 m/s, 1e5 Pa, ...).
    max_step : float
        Largest integration step [s].
    max_steps : int
        Budget of integration steps; exceeding it is a failure.

    Returns
    -------
    SimulationResult

    Raises
    ------
    ParameterError
        For an invalid scenario, stand or option.
    SimulationError
        When the integrator fails (no partial result is returned).

    Notes
    -----
    Implements eqs. (1)-(2) of the reference paper.
    """
    if not isinstance(scenario, Scenario):
        raise ParameterError(f"scenario must be a Scenario, got {scenario!r}")
    rig = get_rig(rig)
    rtol = _check_integrator(integrator, rtol, max_step, max_steps)
    t = sample_times(duration, sample_rate)
    p = pack(rig, scenario)
    y0 = initial_state(p)
    atol = absolute_tolerance(rtol)
    if integrator == "reference":
        states = reference.integrate(p, y0, t, rtol=rtol, atol=atol, max_step=max_step, max_steps=max_steps)
        chans = reference.channels_of(states, p, t)
    else:
        chans = np.empty((d.N_CHANNEL, t.size))
        status, _ = fast.integrate_one(p, y0, t, np.arange(d.N_CHANNEL), rtol, atol, float(max_step),
                                       int(max_steps), chans)
        if status != fast.OK:
            raise SimulationError(f"fast integrator failed ({fast.STATUS_TEXT[status]}) for {scenario}")
    return simulation_result(t, chans, p, y0, rig, scenario, integrator)


@njit(cache=True)
def _energies(chans, p):
    out = np.empty((4, chans.shape[1]))
    y = np.empty(d.N_STATE)
    for i in range(chans.shape[1]):
        for j in range(d.N_STATE):
            y[j] = chans[j, i]
        out[0, i], out[1, i], out[2, i], out[3, i] = d.stored_energy(y, p)
    return out


def simulation_result(t, chans, p, y0, rig, scenario, integrator) -> SimulationResult:
    """The :class:`SimulationResult` of channel histories ``chans`` (N_CHANNEL, n) at times ``t`` [s], with the
    energies computed from the states."""
    energies = _energies(chans, p)
    # kinetic and elastic energies are absolute (never negative); potential and gas energies are changes from t = 0
    energies[1:3] -= energies[1:3, :1].copy()
    named = dict(zip(d.CHANNELS, chans, strict=False))
    return SimulationResult(
        time=t, u1=named["u1"], v1=named["v1"], u2=named["u2"], v2=named["v2"], a1=named["a1"], a2=named["a2"],
        contact_force=named["contact_force"], pneumatic_force=named["pneumatic_force"],
        friction_force=named["friction_force"], top_stop_force=named["top_stop_force"],
        bottom_stop_force=named["bottom_stop_force"], pressure_lower=named["pressure_lower"],
        pressure_upper=named["pressure_upper"], gas_mass_lower=named["gas_mass_lower"],
        gas_mass_upper=named["gas_mass_upper"], kinetic_energy=energies[0], potential_energy=energies[1],
        gas_energy=energies[2], elastic_energy=energies[3], dissipated_energy=named["dissipated_energy"],
        contact_set=named["contact_set"],
        rig=rig, scenario=scenario, integrator=integrator)


def simulate_batch(mass, velocity, pressure_gauge, rig: Rig | None = None, *, overrides=None,
                   duration: float = 0.05, sample_rate: float = 50e3,
                   channels: Sequence[str] = DEFAULT_BATCH_CHANNELS, rtol: float | None = None,
                   dtype=np.float64, max_step: float = MAX_STEP, max_steps: int = MAX_STEPS,
                   device: str | None = None) -> BatchResult:
    """Simulate a batch of scenarios in parallel with the compiled integrator, on the CPU cores or a GPU.

    Parameters
    ----------
    mass, velocity, pressure_gauge : array_like
        M1 [kg], V0 [m/s], p0 [Pa gauge]; broadcast together.
    rig : Rig, optional
        The stand (default ``drop-stand``).
    overrides : mapping, optional
        Dotted stand parameter -> scalar or array (e.g. ``{"contact.stiffness": [1e6, 2e6]}``).
    duration, sample_rate : float
        Record length [s] and sample rate [Hz].
    channels : sequence of str
        Channels to return (any of ``dynamics.CHANNELS``).
    rtol : float, optional
        Relative tolerance (default 1e-9).
    dtype : numpy dtype
        Storage type of the histories (float32 halves the memory).
    max_step, max_steps : float, int
        Largest step [s] and budget of steps per scenario.
    device : {"cpu", "gpu", "auto"}, optional
        Where to integrate: the CPU cores, a CUDA GPU (extra ``impactometer[gpu]``), or the GPU when one is usable
        and the CPU otherwise. Default: the environment variable ``IMPACTOMETER_DEVICE``, else ``"cpu"``. Both run
        the same model and integrator source, so the answers agree to the integration tolerance.

    Returns
    -------
    BatchResult

    Raises
    ------
    ParameterError
        For invalid scenarios (the message names the first bad row), overrides or options.
    DeviceError
        For ``device="gpu"`` without a usable GPU or without the GPU extra.
    SimulationError
        When any scenario fails (no partial result is returned).

    See Also
    --------
    simulate_blocks : the same, a block of scenarios at a time, for batches too large for memory.
    """
    plan = _plan(mass, velocity, pressure_gauge, rig, overrides, duration, sample_rate, channels, rtol, dtype,
                 max_step, max_steps, device)
    n = plan.params.shape[0]
    size = n * plan.index.size * plan.time.size * plan.dtype.itemsize
    if size > memory_bytes():
        raise ParameterError(f"the histories of this batch would take {size / 2**30:.4g} GiB ({n} scenarios × "
                             f"{plan.index.size} channels × {plan.time.size} samples × {plan.dtype.itemsize} bytes), "
                             f"more than the {memory_bytes() / 2**30:.4g} GiB of memory of this machine; expected "
                             "fewer scenarios, channels or samples, or simulate_blocks (a block at a time)")
    return _run(plan, slice(0, n))


def simulate_blocks(mass, velocity, pressure_gauge, rig: Rig | None = None, *, overrides=None,
                    duration: float = 0.05, sample_rate: float = 50e3,
                    channels: Sequence[str] = DEFAULT_BATCH_CHANNELS, rtol: float | None = None,
                    dtype=np.float64, max_step: float = MAX_STEP, max_steps: int = MAX_STEPS,
                    device: str | None = None, block_size: int | None = None) -> Iterator[tuple[slice, BatchResult]]:
    """Simulate a batch a block of scenarios at a time: yields ``(rows, BatchResult)`` with ``rows`` the slice of
    the (flattened, broadcast) scenarios the block holds.

    Only one block of histories is in memory at a time (reduce each block, e.g. to response-map features, before
    asking for the next), so 10^7 scenarios need no more memory than one block plus the packed parameters
    (~300 bytes per scenario). The arguments are those of :func:`simulate_batch`; every argument is checked before
    the first block is simulated.

    Parameters
    ----------
    block_size : int, optional
        Scenarios per block (default: as many as fit in 256 MiB of histories on the CPU, 2 GiB on a GPU).
    """
    plan = _plan(mass, velocity, pressure_gauge, rig, overrides, duration, sample_rate, channels, rtol, dtype,
                 max_step, max_steps, device)
    n = plan.params.shape[0]
    if block_size is None:
        per_scenario = plan.index.size * plan.time.size * plan.dtype.itemsize
        budget = gpu.BLOCK_BYTES if plan.device == "gpu" else _CHUNK_BYTES * 4
        block_size = max(1, budget // per_scenario)
    else:
        check_integer("block_size", block_size, low=1, unit=" (scenarios)")
    for start in range(0, n, int(block_size)):
        rows = slice(start, min(n, start + int(block_size)))
        yield rows, _run(plan, rows)


@dataclass(frozen=True)
class _Plan:
    """A checked batch: stand, sample times, parameter rows, initial states and integrator options."""

    rig: Rig
    time: np.ndarray
    params: np.ndarray
    y0: np.ndarray
    channels: tuple[str, ...]
    index: np.ndarray
    rtol: float
    dtype: np.dtype
    max_step: float
    max_steps: int
    device: str


def _plan(mass, velocity, pressure_gauge, rig, overrides, duration, sample_rate, channels, rtol, dtype, max_step,
          max_steps, device) -> _Plan:
    rig = get_rig(rig)
    rtol = _check_integrator("fast", rtol, max_step, max_steps)
    device = gpu.resolve_device(device)
    channels = (channels,) if isinstance(channels, str) else tuple(channels)
    unknown = [c for c in channels if c not in d.CHANNELS]
    if unknown or not channels:
        raise ParameterError(f"channels must be a non-empty subset of {list(d.CHANNELS)}, got {list(channels)}")
    t = sample_times(duration, sample_rate)
    dtype = np.dtype(np.float64 if dtype is None else dtype)
    if dtype not in (np.float32, np.float64):
        raise ParameterError(f"dtype must be float32 or float64, got {dtype}")
    params = pack_batch(rig, mass, velocity, pressure_gauge, overrides)
    index = np.array([d.CHANNELS.index(c) for c in channels], dtype=np.int64)
    return _Plan(rig=rig, time=t, params=params, y0=initial_states(params), channels=channels, index=index,
                 rtol=rtol, dtype=dtype, max_step=float(max_step), max_steps=int(max_steps), device=device)


def _run(plan: _Plan, rows: slice) -> BatchResult:
    """Integrate the scenarios ``rows`` of ``plan``."""
    params, y0, t, index = plan.params[rows], plan.y0[rows], plan.time, plan.index
    atol = absolute_tolerance(plan.rtol)
    out = np.empty((params.shape[0], index.size, t.size), dtype=plan.dtype)
    status = np.zeros(params.shape[0], dtype=np.int64)
    steps = np.zeros(params.shape[0], dtype=np.int64)
    if plan.device == "gpu":  # the device writes the storage type itself, a memory-bounded block at a time
        gpu.integrate_batch(params, y0, t, index, plan.rtol, atol, plan.max_step, plan.max_steps, out, status,
                            steps)
    else:
        # the kernel writes float64; narrower output goes through one float64 buffer, a chunk of scenarios at a time
        chunk = params.shape[0] if plan.dtype == np.float64 else max(1, _CHUNK_BYTES // (8 * index.size * t.size))
        buffer = None if plan.dtype == np.float64 else np.empty((min(chunk, params.shape[0]), index.size, t.size))
        for start in range(0, params.shape[0], chunk):
            part = slice(start, start + chunk)
            target = out[part] if buffer is None else buffer[:out[part].shape[0]]
            fast.integrate_batch(params[part], y0[part], t, index, plan.rtol, atol, plan.max_step, plan.max_steps,
                                 target, status[part], steps[part])
            if buffer is not None:
                out[part] = target
    bad = np.flatnonzero(status != fast.OK)
    if bad.size:
        i = int(bad[0])
        raise SimulationError(f"fast integrator failed ({fast.STATUS_TEXT[int(status[i])]}) for {bad.size} "
                              f"scenario(s), first: mass={float(params[i, d.MASS])!r} kg, "
                              f"velocity={float(params[i, d.VELOCITY])!r} m/s, "
                              f"pressure_gauge={float(params[i, d.PRESSURE_GAUGE])!r} Pa")
    return BatchResult(time=t, data={c: out[:, j, :] for j, c in enumerate(plan.channels)},
                       mass=params[:, d.MASS].copy(), velocity=params[:, d.VELOCITY].copy(),
                       pressure_gauge=params[:, d.PRESSURE_GAUGE].copy(), params=params, steps=steps, rig=plan.rig)


def compare_integrators(mass, velocity, pressure_gauge, rig: Rig | None = None, *, duration: float = 0.05,
                        sample_rate: float = 200e3, rtol: float | None = None,
                        reference_rtol: float | None = None) -> reference.Agreement:
    """Agreement of the fast and the reference integrator on a set of scenarios (contact force histories).

    Both are sampled at the same instants; see :func:`.reference.agreement` for the measures.
    """
    rig = get_rig(rig)
    ref_rtol = _check_integrator("reference", reference_rtol)
    batch = simulate_batch(mass, velocity, pressure_gauge, rig, duration=duration, sample_rate=sample_rate,
                           channels=("contact_force",), rtol=rtol)
    reference_force = np.empty_like(batch["contact_force"])
    for i, (p, y0) in enumerate(zip(batch.params, initial_states(batch.params), strict=False)):
        states = reference.integrate(p, y0, batch.time, rtol=ref_rtol, atol=absolute_tolerance(ref_rtol))
        reference_force[i] = reference.channels_of(states, p, batch.time)[d.CHANNELS.index("contact_force")]
    return reference.agreement(batch["contact_force"], reference_force, batch.time)


def compare_devices(mass, velocity, pressure_gauge, rig: Rig | None = None, *, device: str = "gpu",
                    duration: float = 0.05, sample_rate: float = 200e3,
                    rtol: float | None = None) -> reference.Agreement:
    """Agreement of the batch on ``device`` with the CPU batch on a set of scenarios (contact force histories).

    Both are sampled at the same instants; see :func:`.reference.agreement` for the measures (relative to the CPU).
    """
    cpu, other = (simulate_batch(mass, velocity, pressure_gauge, rig, duration=duration, sample_rate=sample_rate,
                                 channels=("contact_force",), rtol=rtol, device=name) for name in ("cpu", device))
    return reference.agreement(other["contact_force"], cpu["contact_force"], cpu.time)
