"""Sensor model: what a DAQ records of a simulated (or clean measured) drop test.

The chain, applied per channel: anti-alias low-pass at the internal rate and decimation to the output rate →
accelerometer gravity offset (optional) → additive Gaussian noise → ADC clipping and quantisation.

Anti-alias designs (``anti_alias=``):

- ``"causal"`` (the default, also ``True``): linear-phase FIR (Kaiser window, 16 output periods long) run forward
  only, like the digital filter of a delta-sigma DAQ: both channels are delayed alike by 8 output samples
  (``anti_alias_delay``, also in the metadata as ``anti_alias_delay_s``), so first contact shows 8 samples after
  t = 0 and the pre-trigger samples stay exactly zero.
- ``"zero-phase"``: 8th-order Butterworth at 0.4·fs run forward and backward; no delay but non-causal ringing
  ahead of each contact onset.
- ``"none"`` (also ``False``): plain sampling of the simulation at the output rate (aliasing included).

The causal design is the default because the peak-to-peak identification tolerates it better: over 24 random
scenarios (10-50 kg, 1-3 m/s, noise-free, Kelvin-Voigt and Hunt-Crossley contact, 20 and 50 kHz) its largest
mass error was 0.3-1.4 % against 0.7-3.7 % with the zero-phase design, which also made 10 of 24 Hunt-Crossley
identifications at 20 kHz fail (the table and the script are in ``docs/recordings.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy import signal

from .constants import STANDARD_GRAVITY
from .errors import ParameterError, shown
from .model import simulate_batch
from .model.dynamics import CHANNELS as MODEL_CHANNELS
from .recording import ACCELERATION, FORCE, Recording, check_sample_rate
from .rig import Rig, Scenario, fingerprint, get_rig
from .validation import check_integer, check_real, is_real

#: model channel -> recording channel name
MODEL_TO_RECORDING = {"contact_force": FORCE, "a2": ACCELERATION, "u2": "piston_displacement"}
#: the recording names the sensors can give (besides the model channel names themselves)
RECORDING_TO_MODEL = {v: k for k, v in MODEL_TO_RECORDING.items()}
#: channels that are zero before first contact (the others hold their value at t = 0)
_ZERO_BEFORE_CONTACT = ("contact_force", "a2")
#: lowest internal simulation rate used when the anti-alias filter is on [Hz]
MIN_INTERNAL_RATE = 200e3
#: anti-alias cut-off as a fraction of the output sample rate
CUTOFF_FRACTION = 0.4
#: length of the causal FIR in output sample periods (delay = half of it)
CAUSAL_PERIODS = 16
MIN_SAMPLE_RATE, MAX_SAMPLE_RATE = 5e3, 1e6
#: most samples per channel of a simulated recording
MAX_SAMPLES = 5e7


def _zero_phase(x: np.ndarray, factor: int) -> np.ndarray:
    sos = signal.butter(8, 2.0 * CUTOFF_FRACTION / factor, output="sos")  # normalised to the internal Nyquist
    return signal.sosfiltfilt(sos, x, axis=-1)


def causal_taps(factor: int) -> np.ndarray:
    """Taps of the causal anti-alias FIR at ``factor`` times the output rate (also the model fit's)."""
    return signal.firwin(CAUSAL_PERIODS * factor + 1, 2.0 * CUTOFF_FRACTION / factor, window=("kaiser", 8.0))


def _causal(x: np.ndarray, factor: int) -> np.ndarray:
    return signal.lfilter(causal_taps(factor), [1.0], x, axis=-1)


#: anti-alias design name -> filter(x at the internal rate, decimation factor) -> filtered x
ANTI_ALIAS: dict[str, Callable[[np.ndarray, int], np.ndarray] | None] = {
    "zero-phase": _zero_phase, "causal": _causal, "none": None}
DEFAULT_ANTI_ALIAS = "causal"


def anti_alias_delay(anti_alias: str | bool, sample_rate: float) -> float:
    """Delay the anti-alias design adds to every channel [s] (0 except for ``"causal"``)."""
    return CAUSAL_PERIODS / 2 / sample_rate if _design(anti_alias) == "causal" else 0.0


def internal_layout(design: str, sample_rate: float) -> tuple[int, int]:
    """(decimation factor, internal samples simulated beyond each end) of :func:`record_batch` for ``design``."""
    factor = 1 if design == "none" else max(4, math.ceil(MIN_INTERNAL_RATE / sample_rate))
    return factor, 0 if design == "none" else (CAUSAL_PERIODS + 16) * factor


def _design(anti_alias: str | bool) -> str:
    if anti_alias is True:
        return DEFAULT_ANTI_ALIAS
    if anti_alias is False or anti_alias is None:
        return "none"
    if not isinstance(anti_alias, str) or anti_alias not in ANTI_ALIAS:
        raise ParameterError(f"anti_alias must be True, False or one of {sorted(ANTI_ALIAS)}, got {anti_alias!r}")
    return anti_alias


def _check_rate(sample_rate: float, field: str = "sample_rate") -> float:
    return check_real(field, sample_rate, low=MIN_SAMPLE_RATE, high=MAX_SAMPLE_RATE, unit=" [Hz]")


def _check_nonnegative(value: Any, field: str, unit: str) -> float:
    return check_real(field, value, low=0.0, unit=f" {unit}")


def noise_levels(noise: float | Mapping[str, float], channels: Sequence[str]) -> dict[str, float]:
    """Per-channel noise level (fraction of the channel RMS).

    A single number applies to ``contact_force`` and ``piston_acceleration``; a mapping names channels.
    """
    if isinstance(noise, Mapping):
        unknown = [name for name in noise if name not in channels]
        if unknown:
            raise ParameterError(f"noise names unknown channel(s) {unknown}; channels recorded: {list(channels)}")
        levels = {name: _check_nonnegative(level, f"noise[{name!r}]", "(fraction of RMS)")
                  for name, level in noise.items()}
    else:
        level = _check_nonnegative(noise, "noise", "(fraction of RMS)")
        levels = {name: level for name in (FORCE, ACCELERATION) if name in channels}
    return {name: levels.get(name, 0.0) for name in channels}


def _adc_ranges(adc_range, channels: Mapping[str, np.ndarray]) -> dict[str, tuple[float, float]]:
    """Channel -> (low, high) ADC range; auto range (±1.25·max|x|) for channels not given."""
    def pair(value, name):
        if isinstance(value, (tuple, list)) and len(value) == 2:
            low, high = (float(v) for v in value)
        elif is_real(value):
            low, high = -abs(float(value)), abs(float(value))
        else:
            raise ParameterError(f"adc_range[{name!r}] must be a number (±range) or a (low, high) pair, got {value!r}")
        if not (math.isfinite(low) and math.isfinite(high) and high > low):
            raise ParameterError(f"adc_range[{name!r}] must be finite with high > low, got {value!r}")
        return low, high

    given = adc_range if isinstance(adc_range, Mapping) else {name: adc_range for name in channels}
    unknown = [name for name in given if name not in channels]
    if unknown:
        raise ParameterError(f"adc_range names unknown channel(s) {unknown}; channels recorded: {list(channels)}")
    out = {}
    for name, x in channels.items():
        if given.get(name) is not None:
            out[name] = pair(given[name], name)
        else:
            peak = 1.25 * float(np.max(np.abs(x))) or 1.0
            out[name] = (-peak, peak)
    return out


def quantise(x: np.ndarray, low: float, high: float, bits: int | np.integer | None) -> np.ndarray:
    """Clip ``x`` to [low, high] and, when ``bits`` is given, round it to the 2**bits ADC levels."""
    if bits is None:
        return np.clip(x, low, high)
    step = (high - low) / 2 ** bits
    codes = np.clip(np.round((x - low) / step), 0, 2 ** bits - 1)
    return low + codes * step


def _degrade(channels: dict[str, np.ndarray], factor: int, first: int, *, design: str, levels: dict[str, float],
             rngs: Sequence[np.random.Generator], adc_bits, adc_range, gravity_offset: float | None,
             trigger: int) -> list[dict[str, np.ndarray]]:
    """Filter, decimate and degrade channels of shape (n, samples) at the internal rate.

    ``first`` is the internal index of the first output sample, ``trigger`` the output index of t = 0.
    Returns one dict of output channels per row.
    """
    filt = ANTI_ALIAS[design]
    out: list[dict[str, np.ndarray]] = [{} for _ in rngs]
    for name, x in channels.items():
        y = (filt(x, factor) if filt is not None and factor > 1 else x)[:, first::factor]
        if gravity_offset is not None and name == ACCELERATION:
            y = y - gravity_offset
        for i, rng in enumerate(rngs):
            row = y[i].copy()
            if levels.get(name, 0.0) > 0:
                rms = float(np.sqrt(np.mean(np.square(row[trigger:])))) if row.size > trigger else 0.0
                row = row + rng.normal(0.0, levels[name] * rms, row.size)
            out[i][name] = row
    if adc_bits is not None or adc_range is not None:
        if adc_bits is not None:
            check_integer("adc_bits", adc_bits, low=2, high=32)
        for rec in out:
            for name, (low, high) in _adc_ranges(adc_range, rec).items():
                rec[name] = quantise(rec[name], low, high, adc_bits)
    return out


def _check_seed(seed: Any, field: str = "seed") -> Any:
    """A seed numpy accepts: None, an integer >= 0, a SeedSequence or a Generator; ParameterError otherwise."""
    if seed is None or isinstance(seed, (np.random.SeedSequence, np.random.Generator, np.random.BitGenerator)):
        return seed
    return check_integer(field, seed, low=0, unit=" (or None)")


def _rngs(n: int, seed, seeds) -> tuple[list[np.random.Generator], list[Any]]:
    if seeds is not None:
        seeds = [_check_seed(s, f"seeds[{i}]") for i, s in enumerate(seeds)]
        if len(seeds) != n:
            raise ParameterError(f"seeds must have one entry per scenario ({n}), got {len(seeds)}")
        return [np.random.default_rng(s) for s in seeds], seeds
    seed = _check_seed(seed)
    if seed is None:
        return [np.random.default_rng() for _ in range(n)], [None] * n
    if n == 1:
        return [np.random.default_rng(seed)], [seed]
    children = np.random.SeedSequence(seed).spawn(n)
    return [np.random.default_rng(c) for c in children], [f"{seed}/{i}" for i in range(n)]


def _model_channel(name: str) -> str:
    model = RECORDING_TO_MODEL.get(name, name)
    if model not in MODEL_CHANNELS:
        raise ParameterError(f"extra_channels: unknown channel {name!r}; expected any of "
                             f"{sorted(set(MODEL_CHANNELS) | set(RECORDING_TO_MODEL))}")
    return model


def _fingerprints(rig: Rig, overrides, scenarios, n: int) -> list[str]:
    """Fingerprint of the stand of each of ``n`` scenarios (``overrides`` change it per scenario)."""
    if not overrides:
        return [fingerprint(rig)] * n
    values = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (*scenarios, *overrides.values())))
    rows = np.column_stack([np.atleast_1d(v).ravel() for v in values[3:]])
    cache: dict[tuple, str] = {}
    out = []
    for row in rows:
        key = tuple(row.tolist())
        if key not in cache:
            cache[key] = fingerprint(rig.replace(**dict(zip(overrides, key, strict=True))))
        out.append(cache[key])
    return out


def record_batch(mass, velocity, pressure_gauge, rig: Rig | None = None, *, sample_rate: float = 50e3,
                 duration: float = 0.05, noise: float | Mapping[str, float] = 0.0, seed=None, seeds=None,
                 pre_trigger: float = 0.0, anti_alias: str | bool = True, adc_bits: int | None = None,
                 adc_range=None, include_gravity: bool = False, extra_channels: Sequence[str] = (),
                 overrides=None) -> list[Recording]:
    """Simulated recordings of a batch of drop tests, as the stand's sensors and DAQ would give them.

    Parameters
    ----------
    mass, velocity, pressure_gauge : array_like
        Impacting mass M1 [kg], impact velocity V0 [m/s], charge pressure p0 [Pa gauge]; broadcast together.
    rig : Rig, optional
        The stand (default ``drop-stand``).
    sample_rate : float
        DAQ sample rate [Hz], 5 kHz to 1 MHz.
    duration : float
        Record length after first contact [s].
    noise : float or mapping
        Gaussian noise level as a fraction of each channel's RMS over the record after the trigger; a number
        applies to force and acceleration, a mapping gives levels per channel.
    seed, seeds : int, optional
        ``seeds`` gives one seed per scenario; otherwise per-scenario streams are spawned from ``seed``.
    pre_trigger : float
        Time recorded before first contact [s]; zero force and zero kinematic acceleration before noise.
    anti_alias : {True, False, "causal", "zero-phase", "none"}
        Anti-alias design (see the module notes); True means ``"causal"``.
    adc_bits : int, optional
        ADC resolution [bits]; quantisation over ``adc_range``.
    adc_range : float, (low, high) or mapping, optional
        ADC input range per channel (SI units); samples outside are clipped. Default ±1.25·max|x| per channel.
    include_gravity : bool
        The accelerometer reads specific force, a − g along the downward axis (−g at rest).
    extra_channels : sequence of str
        Further model channels to record (e.g. ``piston_displacement``, ``pressure_lower``).
    overrides : mapping, optional
        Dotted stand parameter -> scalar or array, as in :func:`impactometer.model.simulate_batch`.

    Returns
    -------
    list of Recording
        One per scenario, with truth metadata ``mass_kg``, ``velocity_m_s``, ``pressure_gauge_Pa``, the stand's
        name (``rig``, a label) and the fingerprint of its parameters (``rig_fingerprint``).
    """
    rig = get_rig(rig)
    sample_rate = _check_rate(sample_rate)
    duration = _check_nonnegative(duration, "duration", "[s]")
    pre_trigger = _check_nonnegative(pre_trigger, "pre_trigger", "[s]")
    if duration <= 0:
        raise ParameterError(f"duration must be > 0 [s], got {shown(duration)}")
    if (duration + pre_trigger) * sample_rate > MAX_SAMPLES:
        raise ParameterError(f"duration + pre_trigger must give at most {MAX_SAMPLES:g} samples at "
                             f"{sample_rate:g} Hz, got {duration:g} s + {pre_trigger:g} s")
    design = _design(anti_alias)
    extras = [str(name) for name in extra_channels]
    model_channels = ["contact_force", "a2"] + [_model_channel(name) for name in extras]
    names = [FORCE, ACCELERATION] + [MODEL_TO_RECORDING.get(m, m) for m in model_channels[2:]]
    if len(set(names)) != len(names):
        raise ParameterError(f"extra_channels must not repeat a recorded channel, got {extras}")
    levels = noise_levels(noise, names)

    factor, pad = internal_layout(design, sample_rate)  # pad: filter settling before and after
    rate = factor * sample_rate
    n_pre = int(round(pre_trigger * sample_rate))
    n_out = int(math.floor(duration * sample_rate + 1e-9)) + 1
    batch = simulate_batch(mass, velocity, pressure_gauge, rig, overrides=overrides,
                           duration=(n_out - 1) / sample_rate + pad / rate, sample_rate=rate,
                           channels=tuple(model_channels))
    n = batch.mass.size
    lead = n_pre * factor + pad
    internal = {}
    for model, name in zip(model_channels, names, strict=False):
        data = batch.data[model]
        before = np.zeros((n, lead)) if model in _ZERO_BEFORE_CONTACT else np.repeat(data[:, :1], lead, axis=1)
        internal[name] = np.concatenate([before, data], axis=1)
    rngs, used_seeds = _rngs(n, seed, seeds)
    outputs = _degrade(internal, factor, pad, design=design, levels=levels, rngs=rngs, adc_bits=adc_bits,
                       adc_range=adc_range, gravity_offset=rig.gravity if include_gravity else None,
                       trigger=n_pre)
    prints = _fingerprints(rig, overrides, (mass, velocity, pressure_gauge), n)
    recordings = []
    for i, chans in enumerate(outputs):
        chans = {name: x[:n_pre + n_out] for name, x in chans.items()}
        metadata = {"mass_kg": float(batch.mass[i]), "velocity_m_s": float(batch.velocity[i]),
                    "pressure_gauge_Pa": float(batch.pressure_gauge[i]), "contact_law": rig.contact.law,
                    "rig": rig.name, "rig_fingerprint": prints[i],
                    "noise": {k: v for k, v in levels.items() if v > 0}, "seed": used_seeds[i],
                    "anti_alias": design, "anti_alias_delay_s": anti_alias_delay(design, sample_rate),
                    "adc_bits": adc_bits, "acceleration_includes_gravity": bool(include_gravity)}
        recordings.append(Recording(sample_rate=sample_rate, channels=chans, start_time=-n_pre / sample_rate,
                                    metadata=metadata, source="simulation"))
    return recordings


def record(scenario: Scenario, rig: Rig | None = None, *, sample_rate: float = 50e3, duration: float = 0.05,
           noise: float | Mapping[str, float] = 0.0, seed=None, pre_trigger: float = 0.0,
           anti_alias: str | bool = True, adc_bits: int | None = None, adc_range=None,
           include_gravity: bool = False, extra_channels: Sequence[str] = ()) -> Recording:
    """Simulated recording of one drop test; see :func:`record_batch` for the parameters."""
    if not isinstance(scenario, Scenario):
        raise ParameterError(f"scenario must be a Scenario, got {scenario!r}")
    return record_batch(scenario.mass, scenario.velocity, scenario.pressure_gauge, rig, sample_rate=sample_rate,
                        duration=duration, noise=noise, seeds=[_check_seed(seed)], pre_trigger=pre_trigger,
                        anti_alias=anti_alias, adc_bits=adc_bits, adc_range=adc_range,
                        include_gravity=include_gravity, extra_channels=extra_channels)[0]


def apply_sensors(data: Recording | Mapping[str, Any], *, input_rate: float | None = None,
                  sample_rate: float | None = None, start_time: float = 0.0, noise: float | Mapping = 0.0,
                  seed=None, anti_alias: str | bool = True, adc_bits: int | None = None, adc_range=None,
                  include_gravity: bool = False, gravity: float = STANDARD_GRAVITY,
                  metadata: Mapping[str, Any] | None = None) -> Recording:
    """Degrade a clean signal (a Recording or a mapping of arrays) as the sensors and DAQ would.

    Parameters
    ----------
    data : Recording or mapping of str -> array
        Clean channels in SI units; a mapping needs ``input_rate``.
    input_rate : float, optional
        Sample rate of ``data`` [Hz] (taken from the Recording when one is given).
    sample_rate : float, optional
        Output rate [Hz]; ``input_rate`` divided by an integer (default: no decimation). The anti-alias
        filter acts only when decimating.
    start_time : float
        Time of the first sample [s] when ``data`` is a mapping.
    noise, seed, anti_alias, adc_bits, adc_range, include_gravity
        As in :func:`record_batch`; noise RMS is taken over samples at t >= 0.
    gravity : float
        Gravity subtracted from the acceleration when ``include_gravity`` [m/s²].
    metadata : mapping, optional
        Extra metadata (merged over the recording's).

    Returns
    -------
    Recording
    """
    if isinstance(data, Recording):
        base = data
    elif isinstance(data, Mapping):
        if input_rate is None:
            raise ParameterError("input_rate must be given [Hz] when data is a mapping of arrays")
        base = Recording(sample_rate=input_rate, channels=dict(data), start_time=start_time, source="memory")
    else:
        raise ParameterError(f"data must be a Recording or a mapping of channel arrays, got {type(data).__name__}")
    out_rate = base.sample_rate if sample_rate is None else check_sample_rate(sample_rate, error=ParameterError)
    ratio = base.sample_rate / out_rate
    factor = int(round(ratio))
    if not math.isfinite(ratio) or factor < 1 or abs(ratio - factor) > 1e-9 * ratio:
        raise ParameterError(f"sample_rate must divide the input rate {base.sample_rate:g} Hz by an integer, "
                             f"got {shown(sample_rate)}")
    design = _design(anti_alias)
    names = list(base.channels)
    levels = noise_levels(noise, names)
    g = _check_nonnegative(gravity, "gravity", "[m/s²]")
    first_t = base.start_time
    trigger = max(0, int(math.ceil(-first_t * out_rate - 1e-9)))
    outputs = _degrade({k: v[None, :] for k, v in base.channels.items()}, factor, 0, design=design, levels=levels,
                       rngs=[np.random.default_rng(_check_seed(seed))], adc_bits=adc_bits, adc_range=adc_range,
                       gravity_offset=g if include_gravity else None, trigger=trigger)
    meta = dict(base.metadata)
    meta.update({"noise": {k: v for k, v in levels.items() if v > 0}, "seed": seed})
    if adc_bits is not None:
        meta["adc_bits"] = adc_bits
    if include_gravity:
        meta["acceleration_includes_gravity"] = True
    if factor > 1:  # without decimation no anti-alias filter acts: the recording's own notes stay
        meta.update({"anti_alias": design, "anti_alias_delay_s": anti_alias_delay(design, out_rate)})
    meta.update(metadata or {})
    return Recording(sample_rate=out_rate, channels=outputs[0], start_time=first_t, metadata=meta,
                     source=base.source)
