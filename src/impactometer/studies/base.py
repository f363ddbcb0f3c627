"""What a study is and which studies there are: options, settings, the registry (:data:`STUDIES`, :func:`register`,
:func:`get_study`, :func:`load_studies`), the case grid and per-case seeding.

A study turns a list of *cases* (JSON-ready dicts, one unit of work each) into a tidy table (a list of flat dicts,
one row per case and method). The runner splits the cases into fixed chunks, evaluates them anywhere (this process,
a process pool, a Dask cluster) and persists every finished chunk; a case's random numbers depend only on the seed,
the study name and the case index, so results do not depend on the number of workers or on where they ran.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import json
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import partial
from types import MappingProxyType
from typing import Any

import numpy as np

from ..errors import ParameterError, shown
from ..rig import Rig, get_rig, to_dict
from ..units import parse_quantity
from ..validation import check_flag, check_integer, check_real, is_integer

__all__ = ["MAX_GRID", "MAX_SCENARIOS", "MAX_SEEDS", "MODULES", "PAPER_HEIGHTS", "PAPER_RANGES", "STUDIES", "Row",
           "Setting", "Study", "StudyOptions", "case_seed", "check_params", "get_study", "grid_size", "hashed_seed",
           "indexed_cases", "load_studies", "options_for", "paper_grid", "plotted_by", "register", "relative_error",
           "StudyFigure", "scenario_grid"]

Row = dict[str, Any]

#: the paper's scenario ranges: M1 [kg], V0 [m/s], p0 [Pa gauge]
PAPER_RANGES = MappingProxyType({"mass": (10.0, 50.0), "velocity": (1.0, 3.0), "pressure_gauge": (20e3, 400e3)})
#: drop heights of the paper's response-map grid and random test impacts [m] (masses: ``PAPER_RANGES["mass"]``)
PAPER_HEIGHTS = (0.05, 0.5)
#: largest values per grid axis, noise realisations per case, and grid scenarios times realisations
MAX_GRID, MAX_SEEDS, MAX_SCENARIOS = 40, 100, 200_000
#: longest list a study setting may hold
MAX_SETTING_VALUES = 100


@dataclass(frozen=True)
class Setting:
    """Type and range of a study setting (``--set STUDY.NAME=VALUE``).

    ``kind`` is ``number``, ``numbers`` (a list; one number is taken as a list of one), ``integer``,
    ``integers``, ``choice`` or ``choices``; numbers lie within [``low``, ``high``] (``low`` excluded when
    ``low_open``) and may carry a unit of ``dimension`` (``"20kPa"``), converted to SI.
    """

    kind: str
    low: float | None = None
    high: float | None = None
    dimension: str | None = None
    choices: tuple[str, ...] = ()
    low_open: bool = False

    def check(self, key: str, value: Any) -> Any:
        """``value`` checked and converted (SI, plain Python types); ParameterError naming ``key`` otherwise."""
        many = self.kind in ("numbers", "integers", "choices")
        values = value if isinstance(value, list) else [value]
        if not many and isinstance(value, list):
            raise ParameterError(f"--set {key} must be one {self.kind}, got a list {_short(value)}")
        if not values or len(values) > MAX_SETTING_VALUES:
            raise ParameterError(f"--set {key} must hold 1 to {MAX_SETTING_VALUES} values, got {len(values)}")
        out = [self._one(key, v) for v in values]
        return out if many else out[0]

    def _one(self, key: str, value: Any) -> Any:
        if self.kind in ("choice", "choices"):
            if value not in self.choices:
                raise ParameterError(f"--set {key} must be one of {list(self.choices)}, got {_short(value)}")
            return value
        integer = self.kind in ("integer", "integers")
        if integer and not is_integer(value):
            raise ParameterError(f"--set {key} must be an integer, got {_short(value)}")
        if isinstance(value, (dict, list, type(None))) or (isinstance(value, str) and (self.dimension is None
                                                                                      or len(value) > 40)):
            raise ParameterError(f"--set {key} must be a number{_unit_hint(self.dimension)}, got {_short(value)}")
        number = parse_quantity(value, self.dimension or "number", field=f"--set {key}")
        below = self.low is not None and (number <= self.low if self.low_open else number < self.low)
        if below or (self.high is not None and number > self.high):
            bounds = f"{'(' if self.low_open else '['}{self.low:g}, {self.high:g}]"
            unit = _SI.get(self.dimension or "", "")
            raise ParameterError(f"--set {key} must lie within {bounds}{' ' + unit if unit else ''}, got "
                                 f"{_short(value)}")
        return int(number) if integer else number


_SI = {"pressure": "Pa", "velocity": "m/s", "frequency": "Hz", "time": "s"}


def _short(value: Any) -> str:
    text = json.dumps(value) if isinstance(value, (list, dict, str, int, float, bool, type(None))) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _unit_hint(dimension: str | None) -> str:
    return f" (with an optional {dimension} unit)" if dimension else ""


#: the setting every study has: cases per persisted chunk
CHUNK_SIZE = Setting("integer", 1, 100_000)


def check_params(params: Mapping[str, Any]) -> dict[str, Any]:
    """Study settings ``{"STUDY.SETTING": value}`` checked against each study's settings and converted (SI).

    An unknown study or setting is an error, and so is a value of the wrong type or out of range.
    """
    if not params:
        return {}
    load_studies()
    out = {}
    for key, value in params.items():
        study_name, dot, name = str(key).partition(".")
        if not isinstance(key, str) or not dot or not name:
            raise ParameterError(f"--set must look like STUDY.SETTING=VALUE, got {_short(key)}")
        study = get_study(study_name)
        spec = CHUNK_SIZE if name == "chunk_size" else study.settings.get(name)
        if spec is None:
            known = ", ".join(f"{study_name}.{s}" for s in [*study.settings, "chunk_size"])
            raise ParameterError(f"--set: unknown setting {key!r}; study {study_name!r} has {known}")
        out[key] = spec.check(key, value)
    return out


@dataclass(frozen=True, kw_only=True)
class StudyOptions:
    """Options shared by every study.

    Attributes
    ----------
    rig : The stand (contact law included).
    seed : Root seed of every noise realisation.
    grid : Values per axis of the M1 × V0 × p0 grid over the paper's ranges (5 gives the paper's 125 cases);
        None lets each study use its default size (chosen so that all studies run in about two minutes on two
        cores).
    seeds : Noise realisations per case where a study adds noise.
    noise : Sensor noise of the studies that are not about noise, as a fraction of each channel's RMS.
    sample_rate : DAQ sample rate of the studies that are not about sampling [Hz].
    duration : Record length after first contact [s] (long enough for several contact pulses).
    pre_trigger : Record length before first contact [s]; the identification learns the noise and the offsets
        from it (at 5 kHz a few milliseconds are only a handful of samples).
    params : Study-specific settings (e.g. ``{"noise.levels": [0, 0.05]}``); see each study's ``defaults``.
    rig_is_default : ``rig`` is the package's default stand, not one asked for: a study with a stand of its own
        (``Study.rig``) runs on that one (see :func:`options_for`).
    """

    rig: Rig = field(default_factory=get_rig)
    seed: int = 0
    grid: int | None = None
    seeds: int = 1
    noise: float = 0.01
    sample_rate: float = 50e3
    duration: float = 0.1
    pre_trigger: float = 0.05
    params: Mapping[str, Any] = field(default_factory=dict)
    rig_is_default: bool = False

    def __post_init__(self) -> None:
        check_flag("rig_is_default", self.rig_is_default)
        if not isinstance(self.rig, Rig):
            raise ParameterError(f"rig must be a Rig, got {self.rig!r}")
        for name, least, most in (("seed", 0, 2**63 - 1), ("grid", 2, MAX_GRID), ("seeds", 1, MAX_SEEDS)):
            value = getattr(self, name)
            if name == "grid" and value is None:
                continue
            check_integer(name, value, low=least, high=most, state_range=True)
        if (self.grid or 5) ** 3 * self.seeds > MAX_SCENARIOS:
            raise ParameterError(f"grid³ × seeds must be at most {MAX_SCENARIOS} scenarios, got "
                                 f"{self.grid or 5}³ × {self.seeds} = {(self.grid or 5) ** 3 * self.seeds}")
        for name, low, high in (("noise", 0.0, 1.0), ("sample_rate", 1e3, 1e7), ("duration", 1e-3, 1.0),
                                ("pre_trigger", 0.0, 0.1)):
            check_real(name, getattr(self, name), low=low, high=high, state_range=True)
        if not isinstance(self.params, Mapping):
            raise ParameterError(f"params must be a mapping of setting -> value, got {self.params!r}")
        object.__setattr__(self, "params", check_params(self.params))

    def param(self, study: str, name: str, default: Any) -> Any:
        """Study setting ``study.name`` from ``params``, else ``default``."""
        return self.params.get(f"{study}.{name}", default)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the stand in full)."""
        return {"rig": to_dict(self.rig), "seed": int(self.seed), "grid": self.grid, "seeds": int(self.seeds),
                "noise": float(self.noise), "sample_rate": float(self.sample_rate),
                "duration": float(self.duration), "pre_trigger": float(self.pre_trigger),
                "params": {k: self.params[k] for k in sorted(self.params)}}

    def key(self, study: str) -> str:
        """Fingerprint of these options for ``study`` (persisted chunks are valid only under the same key); the
        settings of other studies do not enter it. The study's settings enter with their values in effect, the
        defaults included, so chunks of a study whose defaults changed (a method added) are never reused."""
        data = self.to_dict()
        data["params"] = {k: v for k, v in data["params"].items() if k.partition(".")[0] == study}
        registered = STUDIES.get(study)
        if registered is not None:
            data["params"] = {**{f"{study}.{k}": v for k, v in registered.defaults.items()}, **data["params"]}
        text = json.dumps({"study": study, **data}, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True, kw_only=True)
class Study:
    """A registered study.

    Attributes
    ----------
    name : Registry name (``impactometer study NAME``).
    title : One-line description.
    figure : The paper's figure it reproduces (or ``""``).
    cases : ``options -> list of case dicts`` (JSON-ready).
    evaluate : ``(cases, options) -> rows``; cases carry their ``case`` index. Must be a module-level function.
    aggregate : ``rows -> small table`` shown in the report.
    summary : ``rows -> [{"quantity", "ours", "paper"}]`` lines of the report's summary.
    drawing : ``(rows, options) -> StudyFigure``: the figure's function and the values computed for it
        (:class:`StudyFigure`; its ``.plot()`` draws it).
    chunk_size : Cases per persisted chunk.
    requires : Modules the study needs; while one is missing the study is listed as unavailable.
    defaults : Study-specific settings and their defaults (override through ``StudyOptions.params``).
    settings : The type and range of each setting in ``defaults`` (:class:`Setting`).
    rig : Name of the stand the study runs on when the options carry the default one (None: the options' stand).
    """

    name: str
    title: str
    figure: str
    cases: Callable[[StudyOptions], list[Row]]
    evaluate: Callable[[list[Row], StudyOptions], list[Row]]
    aggregate: Callable[[list[Row]], list[Row]]
    summary: Callable[[list[Row]], list[Row]]
    drawing: Callable[[list[Row], StudyOptions], StudyFigure]
    chunk_size: int = 25
    requires: tuple[str, ...] = ()
    defaults: Mapping[str, Any] = field(default_factory=dict)
    settings: Mapping[str, Setting] = field(default_factory=dict)
    rig: str | None = None

    def __post_init__(self) -> None:
        unchecked = sorted(set(self.defaults) - set(self.settings))
        if unchecked:
            raise ParameterError(f"study {self.name!r}: settings {unchecked} have no type and range")

    def missing(self) -> list[str]:
        """Required modules that cannot be imported here."""
        out = []
        for module in self.requires:
            try:
                found = importlib.util.find_spec(module) is not None
            except ModuleNotFoundError:
                found = False
            if not found:
                out.append(module)
        return out

    def run(self, options: StudyOptions | None = None) -> list[Row]:
        """Evaluate every case in this process and return the tidy table (no persistence, no progress)."""
        options = StudyOptions() if options is None else options
        if not isinstance(options, StudyOptions):
            raise ParameterError(f"options must be StudyOptions, got {options!r}")
        options = options_for(self, options)
        return self.evaluate(indexed_cases(self, options), options)


#: study modules, in report order
MODULES = ("cases", "parameters", "noise", "sampling", "response_map", "absorption", "valve_design", "absorber_design",
           "peak_force")

#: study name -> Study (filled by the study modules, which register themselves when imported)
STUDIES: dict[str, Study] = {}


def register(study: Study) -> Study:
    """Add ``study`` to :data:`STUDIES` and return it."""
    STUDIES[study.name] = study
    return study


def get_study(name: str) -> Study:
    """The registered study ``name``; an unknown name raises with the list of valid names."""
    if not isinstance(name, str) or name not in STUDIES:
        raise ParameterError(f"study must be one of {sorted(STUDIES)} or 'all', got {shown(name)}")
    return STUDIES[name]


def load_studies() -> dict[str, Study]:
    """Import every study module (each registers itself) and return the registry.

    The modules are imported by name, so that a tree without a study's dependencies still lists the others: a
    study module that cannot be imported because it is absent from this tree is skipped; any other import error
    propagates.
    """
    package = __name__.rpartition(".")[0]
    for module in MODULES:
        try:
            importlib.import_module(f"{package}.{module}")
        except ModuleNotFoundError as exc:
            if not exc.name or not exc.name.startswith(f"{package}.{module}"):
                raise
    return STUDIES


@dataclass(frozen=True)
class StudyFigure:
    """What a study's figure shows: the tidy ``rows`` and the ``values`` the study computed from them for the figure
    (keyword arguments of ``function``, a figure of :mod:`impactometer.plotting.studies`, which draws them and
    computes nothing of the study's own)."""

    function: str
    rows: list[Row]
    values: Mapping[str, Any] = field(default_factory=dict)

    def plot(self) -> Any:
        """The matplotlib figure (matplotlib imported here, when the figure is drawn)."""
        from ..plotting import studies as figures

        return getattr(figures, self.function)(self.rows, **self.values)


def _rows_alone(function: str, rows: list[Row], options: StudyOptions) -> StudyFigure:
    return StudyFigure(function, list(rows))


def plotted_by(function: str) -> Callable[[list[Row], StudyOptions], StudyFigure]:
    """A study's ``drawing`` for a figure that draws the rows alone: ``function`` of
    :mod:`impactometer.plotting.studies` (running a study does not import matplotlib)."""
    return partial(_rows_alone, function)


def options_for(study: Study, options: StudyOptions) -> StudyOptions:
    """``options`` as ``study`` runs them: on the study's own stand when the options carry the default one."""
    if study.rig is None or not options.rig_is_default:
        return options
    return dataclasses.replace(options, rig=get_rig(study.rig), rig_is_default=False)


def indexed_cases(study: Study, options: StudyOptions) -> list[Row]:
    """The cases of ``study`` with their ``case`` index."""
    return [{"case": i, **case} for i, case in enumerate(study.cases(options))]


def hashed_seed(root: int, name: str, *indices: int) -> np.random.SeedSequence:
    """The studies' one seeding scheme: a seed that depends on the ``root`` seed, the ``name`` (a study, or a draw
    every case of a study shares) and the ``indices`` only, never on chunking or workers."""
    return np.random.SeedSequence(int(root), spawn_key=(zlib.crc32(name.encode()), *(int(i) for i in indices)))


def case_seed(options: StudyOptions, study: str, case: int, *more: int) -> np.random.SeedSequence:
    """Seed of one case (and optional sub-draw): a function of the root seed, the study and the indices only."""
    return hashed_seed(options.seed, study, case, *more)


def grid_size(options: StudyOptions, default: int) -> int:
    """Values per grid axis: ``options.grid`` when given, else the study's ``default``."""
    return default if options.grid is None else int(options.grid)


def paper_grid(n: int = 5, *, rig: Rig | None = None, pressures=None) -> list[Row]:
    """The M1 × V0 × p0 grid over the paper's ranges, ``n`` values per axis (5: the paper's 125 cases).

    Parameters
    ----------
    n : int
        Values per axis.
    rig : Rig, optional
        The stand whose rated pressure [Pa gauge] bounds the pressures (default: the built-in stand).
    pressures : sequence of float, optional
        Charge pressures p0 [Pa gauge] instead of ``n`` values over the paper's range.

    Returns
    -------
    list of dict
        ``{"mass" [kg], "velocity" [m/s], "pressure_gauge" [Pa]}`` per case, mass-major, pressure fastest.
    """
    rig = get_rig() if rig is None else rig
    masses = np.linspace(*PAPER_RANGES["mass"], n)
    velocities = np.linspace(*PAPER_RANGES["velocity"], n)
    pressures = np.linspace(*PAPER_RANGES["pressure_gauge"], n) if pressures is None else np.asarray(pressures)
    rated = rig.cylinder.rated_pressure_gauge
    if np.any(pressures > rated):
        raise ParameterError(f"pressures must be <= the rated {rated:g} Pa of {rig.name!r}, "
                             f"got {pressures.max():g}")
    return [{"mass": float(m), "velocity": float(v), "pressure_gauge": float(p)}
            for m in masses for v in velocities for p in pressures]


def scenario_grid(options: StudyOptions, default: int = 5, *, pressures=None) -> list[Row]:
    """The paper's grid (:func:`paper_grid`) on ``options.rig``: ``options.grid`` (else ``default``) values per
    axis."""
    return paper_grid(grid_size(options, default), rig=options.rig, pressures=pressures)


def relative_error(estimate: float, truth: float) -> float:
    """Signed relative error (estimate − truth)/truth [-]."""
    return (estimate - truth) / truth
