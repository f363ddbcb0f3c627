"""The forward model of the model-based identification: the recorded channels a drop test gives, predicted with
the stand model (paper eqs. (1)-(2), the compiled integrator of :mod:`impactometer.model.fast`) and passed through
the sensor model of :mod:`impactometer.sensors` (the same anti-alias filter and decimation as
:func:`~impactometer.sensors.record_batch`), for any contact instant on or between the samples.

The unknowns are held in a parameter vector ``theta`` (:class:`Layout`): M1, V0, the contact instant, the stand
parameters marked uncertain and, when it is not known, the charge pressure; the two sensor offsets are linear and
are handled by the fit (:mod:`.engine`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from numba import njit, prange

from ...errors import IdentificationError, ParameterError, ParameterTypeError, shown
from ...model import dynamics as d
from ...model import fast
from ...model.setup import contact_state, pack
from ...model.simulate import MAX_STEP, absolute_tolerance
from ...rig import CONTACT_LAWS, Rig, Scenario
from ...sensors import ANTI_ALIAS, causal_taps, internal_layout
from ...validation import check_real

#: relative tolerance of the integrations of the fit (the model error it leaves is ~1e-9 of each channel, far
#: below any sensor noise)
FIT_RTOL = 1e-9
#: budget of integration steps of one prediction (a 50 ms record takes 450-560 at FIT_RTOL, whatever the law;
#: parameters far off, e.g. a contact thousands of times too stiff, are refused rather than integrated for seconds)
MAX_FIT_STEPS = 20_000
#: packed parameter -> the range a trial point of a fit may take [SI]; outside it the model is not integrated (the
#: fit steps back), so that no trial point far off costs seconds of integration or breaks the integrator
TRIAL_RANGES = {d.MASS: (1e-3, 1e6), d.VELOCITY: (1e-4, 100.0), d.CONTACT_K: (1.0, 1e15),
                d.CONTACT_C: (0.0, 1e15), d.FRICTION: (0.0, 1e6), d.FRICTION_SCALE: (1e-7, 10.0),
                d.PISTON_MASS: (1e-3, 1e6), d.PRESSURE_GAUGE: (0.0, 1e9), d.DEAD_LOWER: (0.0, 1.0),
                d.DEAD_UPPER: (0.0, 1.0), d.STOP_K: (1.0, 1e13), d.CONTACT_N: (0.2, 10.0), d.CONTACT_M: (0.2, 50.0)}
#: model channels predicted, in the order of the recorded channels (contact force, piston acceleration)
CHANNEL_INDEX = np.array([d.CHANNELS.index("contact_force"), d.CHANNELS.index("a2")], dtype=np.int64)

#: stand parameter -> (packed index, transform, shift or scale) of the fitted variable, which is unbounded:
#: ``log``: ln(value + shift); ``logit``: ln(value/(1 − value)) for a value in (0, 1); ``linear``: value/scale.
#: ``contact.restitution`` is e of the hysteretic law (packed as its unloading stiffness k1/e²),
#: ``contact.set_fraction`` φ of the power law (packed as it is, in the slot of the damping); a dead volume may be
#: zero, so its variable is ln(volume + 1 cm³) (a record tells 0.1 cm³ from none where ln(volume) would lose the
#: slope that brings a volume back from near zero).
STAND_PARAMETERS: dict[str, tuple[int, str, float]] = {
    "contact.stiffness": (d.CONTACT_K, "log", 0.0),
    "contact.damping": (d.CONTACT_C, "log", 0.0),
    "contact.restitution": (d.CONTACT_C, "logit", 0.0),
    "contact.exponent": (d.CONTACT_N, "log", 0.0),
    "contact.unloading_exponent": (d.CONTACT_M, "log", 0.0),
    "contact.set_fraction": (d.CONTACT_C, "logit", 0.0),
    "friction.force": (d.FRICTION, "log", 0.0),
    "friction.velocity_scale": (d.FRICTION_SCALE, "log", 0.0),
    "cylinder.piston_mass": (d.PISTON_MASS, "log", 0.0),
    "cylinder.dead_volume_lower": (d.DEAD_LOWER, "log", 1e-6),
    "cylinder.dead_volume_upper": (d.DEAD_UPPER, "log", 1e-6),
    "stops.stiffness": (d.STOP_K, "log", 0.0),
}
#: the unknowns every fit has (as :data:`STAND_PARAMETERS`); ``contact_time`` is the instant of first contact on
#: the recording's clock, the variable in sample periods from the start value
CORE_PARAMETERS: dict[str, tuple[int, str, float]] = {
    "mass": (d.MASS, "log", 0.0),
    "velocity": (d.VELOCITY, "log", 0.0),
    "contact_time": (-1, "linear", 1.0),
}


def to_variable(value, kind: str, param: float):
    """Fit variable of a physical value (see :data:`STAND_PARAMETERS`)."""
    if kind == "log":
        return np.log(value + param)
    if kind == "logit":
        value = np.clip(value, 1e-12, 1.0 - 1e-12)
        return np.log(value / (1.0 - value))
    return value / param


#: the transforms of the fit variables (see :data:`STAND_PARAMETERS`), by the code the compiled kernels read
KINDS = ("log", "logit", "linear")


@njit(cache=True, error_model="numpy")
def _variable_value(x, code, param):
    """Physical value of the fit variable ``x`` of transform ``KINDS[code]`` (inverse of :func:`to_variable`)."""
    if code == 0:  # a trial point far off: a huge or tiny value, no overflow
        return np.exp(min(max(x, -700.0), 700.0)) - param
    if code == 1:  # e within [1e-13, 1 - 1e-13]: k1/e² stays finite
        return 1.0 / (1.0 + np.exp(-min(max(x, -30.0), 30.0)))
    return x * param


@njit(cache=True, error_model="numpy")
def _variable_values(x, code, param, out):
    for i in range(x.size):
        out[i] = _variable_value(x[i], code, param)


def _from_variable(x, kind: str, param: float):
    """Physical value of a fit variable or an array of them (:func:`variable_value`)."""
    values = np.asarray(x, dtype=float)
    out = np.empty(values.size)
    _variable_values(np.ascontiguousarray(values).reshape(-1), KINDS.index(kind), float(param), out)
    return out.reshape(values.shape) if values.ndim else float(out[0])


@njit(cache=True, error_model="numpy")
def _pack_row(base, x, index, code, param, hysteretic, low, high, out):
    """``out`` := the packed parameters of fit variables ``x`` (a :class:`Layout`'s :attr:`~Layout.codes`, ``base``
    its held values); returns the ``contact_time`` variable's value (sample periods from the layout's origin; 0
    where it is not fitted). The hysteretic law's unloading stiffness k2 = k1/e² follows k1 and e (packed as e).
    A value outside the layout's own bounds ``low``, ``high`` (:attr:`Layout.limits`) is packed as NaN, which the
    one range check refuses (:func:`_outside_ranges`; a contact instant that is not finite)."""
    out[:] = base
    contact = 0.0
    for j in range(index.size):
        value = _variable_value(x[j], code[j], param[j])
        if not low[j] <= value <= high[j]:
            value = np.nan
        if index[j] < 0:
            contact = value
        else:
            out[index[j]] = value
    if hysteretic:
        out[d.CONTACT_C] = out[d.CONTACT_K] / out[d.CONTACT_C] ** 2
    return contact


def contact_parameters(law: str) -> tuple[str, ...]:
    """Dotted names of the parameters of the contact ``law``."""
    return tuple(f"contact.{name}" for name in CONTACT_LAWS[law])


def _check_uncertain(uncertain: Sequence[str] | None, laws: Sequence[str]) -> tuple[str, ...] | None:
    """The stand parameters marked uncertain, checked (None: each law's contact parameters and the seal friction).

    ``"contact"`` stands for every parameter of the fitted law. A name that is no parameter the fit can free, or
    a contact parameter of none of the fitted ``laws``, is a ParameterError naming the valid ones.
    """
    if uncertain is None:
        return None
    valid = ["contact", *STAND_PARAMETERS]
    if isinstance(uncertain, str):
        uncertain = [name.strip() for name in uncertain.split(",") if name.strip()]
    elif not (isinstance(uncertain, Sequence) and all(isinstance(name, str) for name in uncertain)):
        raise ParameterTypeError(f"uncertain must be None, a name or a list of names of stand parameters (any of "
                                 f"{valid}), got {shown(uncertain)}")
    names = tuple(dict.fromkeys(str(name) for name in uncertain))
    for name in names:
        if name not in valid:
            raise ParameterError(f"uncertain names an unknown stand parameter {name!r}; expected any of {valid}")
        if name.startswith("contact.") and not any(name in contact_parameters(law) for law in laws):
            raise ParameterError(f"uncertain names {name!r}, a parameter of none of the contact laws fitted "
                                 f"({', '.join(laws)}); their parameters: "
                                 f"{sorted({p for law in laws for p in contact_parameters(law)})}")
    return names


def free_parameters(law: str, uncertain: tuple[str, ...] | None) -> tuple[str, ...]:
    """The stand parameters a fit with contact ``law`` frees (see :func:`_check_uncertain`)."""
    own = contact_parameters(law)
    if uncertain is None:
        return (*own, "friction.force")
    out: list[str] = []
    for name in uncertain:
        if name == "contact":
            out += own
        elif not name.startswith("contact.") or name in own:
            out.append(name)
    return tuple(dict.fromkeys(out))


#: every parameter a fit can free, by name: the core unknowns, the stand parameters and the charge pressure
PARAMETERS = (*CORE_PARAMETERS, *STAND_PARAMETERS, "pressure_gauge")


def _parameter_spec(name: str, base: np.ndarray) -> tuple[int, str, float]:
    """(packed index, transform, parameter) of the fit variable of parameter ``name`` on the packed stand
    ``base`` (the charge pressure's variable is ln of the absolute pressure)."""
    if name == "pressure_gauge":
        return d.PRESSURE_GAUGE, "log", float(base[d.ATMOSPHERE])
    spec = CORE_PARAMETERS.get(name) or STAND_PARAMETERS.get(name)
    if spec is None:
        raise ParameterError(f"no fit parameter is named {name!r}; expected any of {list(PARAMETERS)}")
    return spec


@dataclass(frozen=True)
class Parameter:
    """One row of a layout's parameter table (:meth:`Layout.table`): the value [SI], the range the model is
    integrated in [SI], whether it is fitted, and its Gaussian prior (mean, σ) [SI] or None."""

    name: str
    value: float
    bounds: tuple[float, float]
    free: bool
    prior: tuple[float, float] | None


@dataclass(frozen=True)
class Layout:
    """Which unknowns a fit has and how its variables map onto the packed stand parameters.

    ``names`` lists the nonlinear unknowns (the core ones, then the stand parameters, then ``pressure_gauge`` when
    it is fitted) and ``specs`` their (packed index, transform, parameter); ``base`` is the packed parameter vector
    of the stand with the law and known values (the held parameters); ``origin`` is the contact instant [s] from
    which the ``contact_time`` variable counts sample periods; ``priors`` the Gaussian priors on unknowns, each
    (index into ``names``, mean, σ) of its fit variable and one more residual row (:meth:`with_prior`); ``bounds``
    the layout's own bounds, each (name, lower, upper) [SI] (:meth:`with_bounds`).
    """

    names: tuple[str, ...]
    specs: tuple[tuple[int, str, float], ...]
    base: np.ndarray
    law: str
    origin: float
    sample_rate: float
    priors: tuple[tuple[int, float, float], ...] = ()
    bounds: tuple[tuple[str, float, float], ...] = ()

    def with_prior(self, name: str, mean: float, sigma: float) -> Layout:
        """This layout with a Gaussian prior of ``mean`` and ``sigma`` [SI] on the unknown ``name``: the residual row
        (variable − variable(mean))/σ', σ' the prior's σ through the slope of the transform at the mean (a log
        variable: the relative σ)."""
        j = self.names.index(name)
        _, kind, param = self.specs[j]
        mean_variable = float(to_variable(self._scaled(name, mean), kind, param))
        spread = sigma / abs(self.derivative(name, mean_variable))
        return replace(self, priors=(*self.priors, (j, mean_variable, float(spread))))

    def with_free(self, name: str) -> Layout:
        """This layout with the held parameter ``name`` (any of :data:`PARAMETERS`) an unknown, from its held
        value: a table edit (the stand parameters go before ``pressure_gauge``, which stays last)."""
        if name in self.names:
            return self
        spec = _parameter_spec(name, self.base)
        at = self.names.index("pressure_gauge") if "pressure_gauge" in self.names else len(self.names)
        return replace(self, names=(*self.names[:at], name, *self.names[at:]),
                       specs=(*self.specs[:at], spec, *self.specs[at:]),
                       priors=tuple((j + (j >= at), mean, spread) for j, mean, spread in self.priors))

    def with_bounds(self, name: str, lower: float, upper: float) -> Layout:
        """This layout with the parameter ``name`` kept within [``lower``, ``upper``] [SI] (either may be infinite):
        a table edit. A trial point of a fit outside them is refused by the one range check of every prediction
        (the solver steps back), as one outside the range the model is integrated in, which still applies. The
        held value, or the prior's mean, must lie inside."""
        index, _, _ = _parameter_spec(name, self.base)
        lower = check_real("lower", lower, finite=False, unit=f" [SI] (the lower bound of {name})")
        upper = check_real("upper", upper, low=lower, low_open=True, finite=False,
                           unit=f" [SI] (the upper bound of {name}, above its lower bound)")
        row = next((row for row in self.table() if row.name == name), None)
        held = row is not None and not row.free
        value = None if row is None else row.value if held else row.prior[0] if row.prior is not None else None
        if value is not None and not lower <= value <= upper:
            raise ParameterError(f"{name}'s bounds must hold its {'held value' if held else 'prior mean'} "
                                 f"{value:g}, got [{lower:g}, {upper:g}]", field=name,
                                 expected=f"bounds holding {value:g}")
        return replace(self, bounds=(*((n, lo, hi) for n, lo, hi in self.bounds if n != name), (name, lower, upper)))

    def with_held(self, name: str, value: float) -> Layout:
        """This layout with the unknown ``name`` held at ``value`` [SI] (its prior dropped): a table edit. The
        contact instant is always fitted."""
        index, _, _ = _parameter_spec(name, self.base)
        if index < 0:
            raise ParameterError(f"the contact instant cannot be held; hold any of "
                                 f"{[n for n in PARAMETERS if n != 'contact_time']}")
        low, high = next(((lo, hi) for n, lo, hi in self.bounds if n == name), (-math.inf, math.inf))
        value = check_real(name, value, low=low, high=high, unit=" [SI] (the layout's bounds)")
        base = self.base.copy()
        base[index] = value
        if name not in self.names:
            return replace(self, base=base)
        j = self.names.index(name)
        return replace(self, names=self.names[:j] + self.names[j + 1:], specs=self.specs[:j] + self.specs[j + 1:],
                       base=base, priors=tuple((k - (k > j), mean, spread) for k, mean, spread in self.priors
                                               if k != j))

    def table(self, x: np.ndarray | None = None) -> tuple[Parameter, ...]:
        """Every parameter the fit can free, by name: its value (an unknown's at the fit variables ``x``, else at
        none: NaN; a held one's), the range the solver's one range check keeps it in (:func:`_outside_ranges`: the
        range the model is integrated in, within the layout's own bounds), whether it is free, and its prior."""
        values = {} if x is None else self.values(np.asarray(x, dtype=float)[:len(self.names)])
        priors = {self.names[j]: (mean, spread) for j, mean, spread in self.priors}
        rows = []
        for name in PARAMETERS:
            index, kind, param = _parameter_spec(name, self.base)
            free = name in self.names
            if free:
                value = values.get(name, math.nan)
            elif index < 0:
                continue
            else:
                value = float(self.base[index])
            low, high = (-math.inf, math.inf) if index < 0 else (0.0, 1.0) if kind == "logit" else \
                TRIAL_RANGES[index]
            for _, lower, upper in (bound for bound in self.bounds if bound[0] == name):
                low, high = max(low, lower), min(high, upper)
            prior = None
            if name in priors:
                mean, spread = priors[name]
                middle = float(self.values(np.r_[np.zeros(self.names.index(name)), mean])[name])
                prior = (middle, spread * abs(self.derivative(name, mean)))
            rows.append(Parameter(name=name, value=value, bounds=(low, high), free=free, prior=prior))
        return tuple(rows)

    def variables(self, values: dict[str, float]) -> np.ndarray:
        """Fit variables of physical values (name -> value [SI])."""
        out = np.empty(len(self.names))
        for i, (name, (_, kind, param)) in enumerate(zip(self.names, self.specs, strict=True)):
            out[i] = to_variable(self._scaled(name, values[name]), kind, param)
        return out

    def values(self, x: np.ndarray) -> dict[str, float]:
        """Physical values [SI] of fit variables ``x``."""
        out = {}
        for name, xi, (_, kind, param) in zip(self.names, x, self.specs, strict=False):
            value = float(_from_variable(xi, kind, param))
            out[name] = self.origin + value / self.sample_rate if name == "contact_time" else value
        return out

    def _scaled(self, name: str, value: float) -> float:
        """``value`` [SI] of the parameter ``name`` as its variable counts it before the transform: the contact
        instant [s] in sample periods from ``origin``, any other as it is."""
        return (value - self.origin) * self.sample_rate if name == "contact_time" else value

    def derivative(self, name: str, x: float) -> float:
        """d(value)/d(variable) of the unknown ``name`` at variable ``x`` [SI per variable unit]."""
        _, kind, param = self.specs[self.names.index(name)]
        if kind == "log":
            return float(np.exp(x))
        if kind == "logit":
            e = float(_from_variable(x, kind, param))
            return e * (1.0 - e)
        return param / self.sample_rate if name == "contact_time" else param

    @cached_property
    def codes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The packed index (-1: the contact instant), transform code (:data:`KINDS`) and parameter of each
        unknown, as the compiled kernels read them (:func:`_pack_row`)."""
        return (np.array([index for index, _, _ in self.specs], dtype=np.int64),
                np.array([KINDS.index(kind) for _, kind, _ in self.specs], dtype=np.int64),
                np.array([param for _, _, param in self.specs], dtype=float))

    @cached_property
    def limits(self) -> tuple[np.ndarray, np.ndarray]:
        """The layout's own bounds of each unknown as :func:`_pack_row` reads them: lower and upper [SI; the contact
        instant in sample periods from ``origin``], infinite where it has none."""
        low, high = np.full(len(self.names), -math.inf), np.full(len(self.names), math.inf)
        for name, lower, upper in self.bounds:
            if name in self.names:
                j = self.names.index(name)
                low[j], high[j] = self._scaled(name, lower), self._scaled(name, upper)
        return low, high

    def packed(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Packed parameter rows (m, N_PARAM) and contact instants (m,) [s] of fit variable rows (m, q); a value
        outside the layout's bounds is NaN (:func:`_pack_row`)."""
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        params = np.empty((rows.shape[0], self.base.size))
        shifts = np.empty(rows.shape[0])
        index, code, param = self.codes
        low, high = self.limits
        for s in range(rows.shape[0]):
            shifts[s] = _pack_row(self.base, np.ascontiguousarray(rows[s]), index, code, param,
                                 self.law == "hysteretic", low, high, params[s])
        times = self.origin + shifts / self.sample_rate if "contact_time" in self.names else np.zeros(rows.shape[0])
        return params, times


def make_layout(rig: Rig, law: str, free: tuple[str, ...], *, pressure_gauge: float | None, contact_time: float,
                sample_rate: float, mass: float | None = None, velocity: float | None = None,
                pressure_gauge_std: float = 0.0) -> Layout:
    """The :class:`Layout` of a fit on ``rig`` with contact ``law`` freeing the stand parameters ``free``, the
    charge pressure known (``pressure_gauge`` [Pa gauge]; held where ``pressure_gauge_std`` [Pa] is 0, else fitted
    with the Gaussian prior ``pressure_gauge`` ± ``pressure_gauge_std``) or fitted (None; the variable is ln of the
    absolute pressure),
    counting the contact instant from ``contact_time`` [s]; M1 held at ``mass`` [kg] and V0 at ``velocity`` [m/s]
    when they are given."""
    stand = rig if rig.contact.law == law else rig.with_contact(law)
    base = pack(stand, Scenario(mass=1.0, velocity=1.0, pressure_gauge=pressure_gauge or 0.0))
    if law == "hysteretic":  # packed as e (see Layout.packed)
        base[d.CONTACT_C] = float(stand.contact.restitution or 0.0)
    core = dict(CORE_PARAMETERS)
    if mass is not None:
        base[d.MASS] = mass
        del core["mass"]
    if velocity is not None:
        base[d.VELOCITY] = velocity
        del core["velocity"]
    names = [*core, *free]
    specs = [*core.values(), *(STAND_PARAMETERS[name] for name in free)]
    layout = Layout(names=tuple(names), specs=tuple(specs), base=base, law=law, origin=float(contact_time),
                    sample_rate=float(sample_rate))
    if pressure_gauge is None or pressure_gauge_std > 0.0:
        layout = layout.with_free("pressure_gauge")
    if pressure_gauge is not None and pressure_gauge_std > 0.0:
        layout = layout.with_prior("pressure_gauge", pressure_gauge, pressure_gauge_std)
    return layout


#: stand parameters that may be zero -> the value a fit starts from where the stand's is zero [SI] (a start at zero
#: would sit on the edge of the range the model is integrated in: every step towards smaller values refused)
ZERO_START = {"cylinder.dead_volume_lower": 1e-6, "cylinder.dead_volume_upper": 1e-6}


def stand_values(rig: Rig, law: str, free: tuple[str, ...]) -> dict[str, float]:
    """Start values [SI] of the freed stand parameters: those of ``rig`` for its own law, else the law's
    defaults (a zero one from :data:`ZERO_START`)."""
    contact = rig.contact if rig.contact.law == law else rig.with_contact(law).contact
    out = {}
    for name in free:
        section, _, attr = name.partition(".")
        value = float(getattr(contact if section == "contact" else getattr(rig, section), attr))
        out[name] = value if value > 0.0 else ZERO_START.get(name, value)
    return out


@dataclass(frozen=True)
class Grid:
    """The sample instants of a recording and the sensor model its channels went through.

    ``design`` is the anti-alias design (:data:`impactometer.sensors.ANTI_ALIAS`); the model is evaluated at
    ``factor`` times the sample rate over the record and ``pad`` internal samples beyond each end, filtered as
    :func:`~impactometer.sensors.record_batch` filters, and decimated.
    """

    start_time: float
    sample_rate: float
    size: int
    design: str
    factor: int
    pad: int
    taps: np.ndarray
    #: valve Z's opening schedule: instants on the recording's clock [s] (increasing) and the opening [-] of the
    #: fully open valve held from each (zero-order hold; closed before the first); None: the valve of the parameters
    valve: tuple[np.ndarray, np.ndarray] | None = None

    @cached_property
    def instants(self) -> np.ndarray:
        """Internal instants relative to the first sample [s] (made once per grid: every prediction reads them)."""
        n_int = 2 * self.pad + (self.size - 1) * self.factor + 1
        return (np.arange(n_int) - self.pad) / (self.factor * self.sample_rate)


def _make_grid(start_time: float, sample_rate: float, size: int, design: str, opening=None) -> Grid:
    """The :class:`Grid` of a recording of ``size`` samples from ``start_time`` [s] at ``sample_rate`` [Hz];
    ``opening``: valve Z's opening [-] at each of its samples (:func:`_valve_schedule`), None or all zero: closed."""
    if design not in ANTI_ALIAS:
        raise IdentificationError(f"anti_alias must be one of {sorted(ANTI_ALIAS)}, got {design!r}")
    factor, pad = internal_layout(design, sample_rate)
    taps = causal_taps(factor) if design == "causal" else np.ones(1)
    valve = None if opening is None else _valve_schedule(opening, start_time, sample_rate)
    return Grid(start_time=float(start_time), sample_rate=float(sample_rate), size=int(size), design=design,
                factor=factor, pad=pad, taps=taps[::-1].copy(), valve=valve)


def _valve_schedule(opening, start_time: float, sample_rate: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The opening schedule of :class:`Grid` from valve Z's opening [-] sampled with a record (``start_time``
    [s], ``sample_rate`` [Hz]): each sample's opening held from its instant, runs of one value merged; None for a
    valve closed throughout (the prediction is then the closed-valve one, bit for bit).

    Raises
    ------
    ParameterError
        For an opening outside [0, 1] or not finite.
    """
    opening = np.asarray(opening, dtype=float).ravel()
    if not np.all(np.isfinite(opening)) or np.any(opening < 0.0) or np.any(opening > 1.0):
        bad = opening[~(np.isfinite(opening) & (opening >= 0.0) & (opening <= 1.0))][0]
        raise ParameterError(f"valve opening must be within [0, 1] [-] at every sample, got {bad!r}")
    if not np.any(opening > 0.0):
        return None
    change = np.flatnonzero(np.diff(opening, prepend=0.0) != 0.0)
    return start_time + change / float(sample_rate), opening[change].copy()


#: the packed parameters a trial point is checked on, and their ranges (:data:`TRIAL_RANGES`)
_RANGE_INDEX = np.array(list(TRIAL_RANGES), dtype=np.int64)
_RANGE_LOW, _RANGE_HIGH = (np.array([bounds[k] for bounds in TRIAL_RANGES.values()]) for k in (0, 1))
#: status of a row whose charge cannot carry the piston (it would rest on the bottom stop), and of one outside
#: :data:`TRIAL_RANGES`
NO_START, OUTSIDE = -100, -101


@njit(cache=True, error_model="numpy")
def _outside_ranges(p):
    """The first packed index of row ``p`` outside :data:`TRIAL_RANGES` (a NaN is outside); -1 where none is: the
    one range check of every prediction of a fit."""
    for k in range(_RANGE_INDEX.size):
        value = p[_RANGE_INDEX[k]]
        if not (_RANGE_LOW[k] <= value <= _RANGE_HIGH[k]):
            return _RANGE_INDEX[k]
    return -1


#: what :func:`_contact_refusal` finds of a contact instant: taken, not finite, before the earliest
CONTACT_TAKEN, CONTACT_NOT_FINITE, CONTACT_EARLY = 0, 1, 2


@njit(cache=True, error_model="numpy")
def _contact_refusal(contact, earliest):
    """The one contact-instant check of every prediction of a fit: :data:`CONTACT_EARLY` for a contact instant
    ``contact`` [s] before ``earliest`` [s] (before the part of the record the model is predicted on), else
    :data:`CONTACT_NOT_FINITE` for one that is not finite, else :data:`CONTACT_TAKEN`."""
    if contact < earliest:
        return CONTACT_EARLY
    return CONTACT_TAKEN if np.isfinite(contact) else CONTACT_NOT_FINITE


@njit(cache=True, error_model="numpy")
def _predict_row(p, y0, instants, shift, valve_times, valve_open, channel_index, rtol, atol, max_step, max_steps,
                 out):
    """One row of a prediction on the calling thread: the channels ``out`` (channels, instants) at ``instants -
    shift`` after contact, zero before the last instant before it, which is integrated too (it holds the state at
    contact: a contact force that jumps at first touch shares the jump with it, fast.share_jump). ``y0`` is scratch
    for the state at contact. Valve Z's opening is held at ``valve_open[i]`` [-] from ``valve_times[i]`` [s after
    the first sample] (closed before the first; :func:`_integrate_schedule`); an empty schedule: the valve of the
    parameters, integrated in one piece. Returns the integrator's status, :data:`OUTSIDE` or :data:`NO_START`."""
    if _outside_ranges(p) >= 0:
        return OUTSIDE
    if not contact_state(p, y0):
        return NO_START
    t = instants - shift
    first = max(np.searchsorted(t, 0.0, side="right") - 1, 0)
    for j in range(channel_index.size):
        out[j, :first] = 0.0
    if valve_times.size:
        return _integrate_schedule(p, y0, t, first, valve_times - shift, valve_open, channel_index, rtol, atol,
                                   max_step, max_steps, out)
    status, _ = fast.integrate_one(p, y0, t[first:], channel_index, rtol, atol, max_step, max_steps,
                                   out[:, first:])
    return status


@njit(cache=True, error_model="numpy")
def _integrate_schedule(p, y0, t, first, changes, valve_open, channel_index, rtol, atol, max_step, max_steps, out):
    """The channels ``out[:, first:]`` at the instants ``t[first:]`` after contact [s] from the state at contact
    ``y0``, valve Z's opening held at ``valve_open[i]`` [-] from ``changes[i]`` [s after contact] (closed before the
    first): the model (the stand's own flow law, :func:`.dynamics.rhs` at the area opening · A_max) is integrated
    from one change of the opening to the next, each piece restarted from the state where the last ended (the
    opening is a step there, the right-hand side is not smooth across it). Returns the integrator's status."""
    n = out.shape[1]
    n_ch = channel_index.size
    index = np.empty(n_ch + d.N_STATE, dtype=np.int64)  # the channels and the whole state (where a piece ends)
    index[:n_ch] = channel_index
    for i in range(d.N_STATE):
        index[n_ch + i] = i
    q = p.copy()
    y = y0.copy()
    b = np.searchsorted(changes, 0.0, side="right")  # the next change after contact
    q[d.VALVE_AREA] = valve_open[b - 1] * p[d.VALVE_MAX_AREA] if b > 0 else 0.0
    t0 = 0.0
    i = first
    while i < n:
        last = b >= changes.size
        t_end = math.inf if last else changes[b]
        j = i
        while j < n and t[j] <= t_end:
            j += 1
        size = j - i if last else j - i + 1
        if size > 0:
            t_piece = np.empty(size)
            for m in range(j - i):
                t_piece[m] = t[i + m] - t0
            if not last:
                t_piece[size - 1] = t_end - t0
            piece = np.empty((index.size, size))
            status, _ = fast.integrate_one(q, y, t_piece, index, rtol, atol, max_step, max_steps, piece)
            if status != fast.OK:
                return status
            for c in range(n_ch):
                out[c, i:j] = piece[c, :j - i]
            for c in range(d.N_STATE):
                y[c] = piece[n_ch + c, size - 1]
        if last:
            break
        t0 = t_end
        q[d.VALVE_AREA] = valve_open[b] * p[d.VALVE_MAX_AREA]
        b += 1
        i = j
    return fast.OK


@njit(cache=True, parallel=True, error_model="numpy")
def _predict_rows(params, instants, shifts, valve_times, valve_open, channel_index, rtol, atol, max_step, max_steps,
                  out, status):
    """:func:`_predict_row` of every row on the thread pool (``out`` (m, channels, n) filled at the first n
    instants: :func:`.fast.integrate_into`)."""
    for s in prange(params.shape[0]):
        status[s] = _predict_row(params[s], np.empty(d.N_STATE), instants, shifts[s], valve_times, valve_open,
                                 channel_index, rtol, atol, max_step, max_steps, out[s])


@njit(cache=True, error_model="numpy")
def _predict_in_turn(params, instants, shifts, valve_times, valve_open, channel_index, rtol, atol, max_step,
                     max_steps, out, status):
    """:func:`_predict_row` of every row, one after the other on the calling thread (``out`` as
    :func:`_predict_rows`)."""
    y0 = np.empty(d.N_STATE)
    for s in range(params.shape[0]):
        status[s] = _predict_row(params[s], y0, instants, shifts[s], valve_times, valve_open, channel_index, rtol,
                                 atol, max_step, max_steps, out[s])


def _schedule(grid: Grid | None) -> tuple[np.ndarray, np.ndarray]:
    """The grid's valve schedule as the compiled predictor reads it: the instants of the changes after the first
    sample [s] and the openings [-], both empty (typed float arrays) for the valve of the parameters (no grid, or
    :attr:`Grid.valve` None)."""
    if grid is None or grid.valve is None:
        return np.empty(0), np.empty(0)
    times, opening = grid.valve
    return (np.ascontiguousarray(np.asarray(times, dtype=float) - grid.start_time),
            np.ascontiguousarray(opening, dtype=float))


def _predict(grid: Grid, params: np.ndarray, contact_times: np.ndarray, *, in_turn: bool = False) -> np.ndarray:
    """Recorded contact force [N] and piston acceleration [m/s²] without offsets and noise, shape (m, 2, size), of
    packed parameter rows (m, N_PARAM) with first contact at ``contact_times`` (m,) [s] on the recording's clock;
    ``in_turn``: on the calling thread, one row after the other (the same numbers; a launch on the thread pool
    cost 1-10 ms on a loaded machine, twenty integrations of a first window).

    Raises
    ------
    IdentificationError
        For a row outside :data:`TRIAL_RANGES` or a contact instant that is not finite, when the stand cannot
        carry the piston at a row's pressure or the integrator fails.
    """
    params = np.ascontiguousarray(params, dtype=float)
    if not np.all(np.isfinite(contact_times)):
        raise IdentificationError("the model is not integrated at a contact instant that is not finite")
    instants = grid.instants
    out = np.empty((params.shape[0], 2, _read(grid)))  # the instants after the last that the filter reads: none
    status = np.zeros(params.shape[0], dtype=np.int64)
    shifts = np.asarray(contact_times, dtype=float) - grid.start_time
    kernel = _predict_in_turn if in_turn else _predict_rows  # the same numbers: each row is integrated alone
    kernel(params, instants, shifts, *_schedule(grid), CHANNEL_INDEX, FIT_RTOL, absolute_tolerance(FIT_RTOL),
           MAX_STEP, MAX_FIT_STEPS, out, status)
    if np.any(status != fast.OK):
        i = int(np.flatnonzero(status != fast.OK)[0])
        if status[i] == OUTSIDE:
            index = int(_outside_ranges(params[i]))
            low, high = TRIAL_RANGES[index]
            raise IdentificationError(f"the model is not integrated at packed parameter {index} = "
                                      f"{params[i, index]!r}, outside [{low:g}, {high:g}]")
        if status[i] == NO_START:
            raise IdentificationError("the model cannot start: the charge is too low to carry the piston")
        raise IdentificationError(f"the model's integration failed ({fast.STATUS_TEXT[int(status[i])]}) at "
                                  f"M1 = {params[i, d.MASS]:.4g} kg, V0 = {params[i, d.VELOCITY]:.4g} m/s")
    return _sensed(grid, out)


def _read(grid: Grid) -> int:
    """The internal instants the grid's anti-alias filter reads, from the first (all of them but the pad after the
    last sample under the causal FIR, :func:`_fir_decimate`)."""
    return grid.pad + (grid.size - 1) * grid.factor + 1 if grid.design == "causal" else grid.instants.size


def _sensed(grid: Grid, internal: np.ndarray) -> np.ndarray:
    """Channels (..., size) of internal histories (..., len(grid.instants)) through the grid's anti-alias filter
    and decimation (the causal FIR evaluated at the kept samples only)."""
    end = grid.pad + (grid.size - 1) * grid.factor + 1
    if grid.design == "causal":
        flat = np.ascontiguousarray(internal).reshape(-1, internal.shape[-1])
        out = np.empty((flat.shape[0], grid.size))
        _fir_decimate(flat, grid.taps, grid.pad - grid.taps.size + 1, grid.factor, out)
        return out.reshape(*internal.shape[:-1], grid.size)
    filt = ANTI_ALIAS[grid.design]
    y = internal if filt is None or grid.factor == 1 else filt(internal, grid.factor)
    return np.ascontiguousarray(y[..., grid.pad:end:grid.factor])


@njit(cache=True, error_model="numpy", fastmath=True)
def _fir_decimate(x, reversed_taps, first, step, out):
    """out[r, i] = Σ_m reversed_taps[m]·x[r, first + i·step + m]: a causal FIR evaluated at every ``step``-th
    sample only (zero, uncomputed, where the window holds only the zeros before contact). ``fastmath`` lets the
    compiler reorder the sum of each output (SIMD lanes): the last bits change, the time falls by half."""
    for r in range(x.shape[0]):
        nonzero = 0
        while nonzero < x.shape[1] and x[r, nonzero] == 0.0:
            nonzero += 1
        for i in range(out.shape[1]):
            k = first + i * step
            if k + reversed_taps.size <= nonzero:
                out[r, i] = 0.0
                continue
            acc = 0.0
            for m in range(reversed_taps.size):
                acc += reversed_taps[m] * x[r, k + m]
            out[r, i] = acc


#: a re-contact after a free flight of the mass longer than this ends the span a fit reads [s]. The flights of
#: stage A (the first rebounds) last up to ~17 ms on the built-in stands and a fit follows them (its ±2σ holds);
#: after a flight of 73 ms (10 kg at 3 m/s on 50 kPa, the mass thrown off by the pad) it did not
LONG_FLIGHT = 0.03
#: the span a fit reads ends this long before the event that ends it [s]
HORIZON_GUARD = 1e-3


def _horizon(layout: Layout, x: np.ndarray, span: float, grid: Grid | None = None) -> tuple[float, str]:
    """How long after first contact [s] a fit at variables ``x`` (of ``layout``) reads a record of ``span`` [s]
    after contact, and why (``grid``: the record's, whose valve opening schedule the model follows).

    The model at ``x`` is integrated over the span and the fit stops ``HORIZON_GUARD`` before the first of: the
    piston's return onto its top stop, and a re-contact of the mass after a free flight longer than
    ``LONG_FLIGHT``. Each is an instant that the whole stroke (or the whole flight) decides: the likelihood
    narrows around it far below the scale of its own curvature, so that a fit through it lands on a neighbouring
    minimum (errors of 5-10 stated σ on 100 ms pad records where the piston returns). The record up to there is
    read in full; its answer is as accurate as the samples before, with a standard error that holds.
    """
    params, contact = layout.packed(x[None, :len(layout.names)])
    times = np.arange(1, max(int(span * layout.sample_rate), 1) + 1) / layout.sample_rate  # after contact
    index = np.array([d.U2, d.CHANNELS.index("contact_force")], dtype=np.int64)
    out = np.empty((2, times.size))
    valve_times, valve_open = _schedule(grid)
    if grid is not None and valve_times.size:
        valve_times = valve_times - (float(contact[0]) - grid.start_time)  # after contact
    status = _predict_row(params[0], np.empty(d.N_STATE), times, 0.0, valve_times, valve_open, index, FIT_RTOL,
                          absolute_tolerance(FIT_RTOL), MAX_STEP, MAX_FIT_STEPS, out)
    if status != fast.OK:
        return span, "the whole record (the model's course over it could not be integrated)"
    raised, touching = -out[0] > 0.0, out[1] > 0.0
    ends = []
    left = np.flatnonzero(~raised)
    if left.size and (back := np.flatnonzero(raised[left[0]:])).size:
        ends.append((times[left[0] + back[0]], "the piston's return onto its top stop"))
    changes = np.flatnonzero(np.diff(touching.astype(np.int8)))
    for off, on in zip(changes[:-1], changes[1:], strict=False):
        if touching[off] and times[on] - times[off] > LONG_FLIGHT:
            ends.append((times[on], f"a re-contact after a free flight of {(times[on] - times[off]) * 1e3:.3g} ms"))
            break
    if not ends:
        return span, "the whole record"
    instant, why = min(ends)
    return min(span, max(instant - HORIZON_GUARD, 0.0)), f"{HORIZON_GUARD * 1e3:g} ms before {why}"
