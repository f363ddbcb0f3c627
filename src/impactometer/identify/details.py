"""What an identification method used, typed: frozen dataclasses read by attribute, SI values without unit
suffixes, and the JSON form (unit suffixes in its keys) in ``to_dict``.

Each is also a read-only mapping by the names of the plain dict it replaces (``details["equations"]["extrema"]``,
``details.get("caution")``): the form :meth:`.result.Identification.to_dict` reports and that code written against
that dict keeps reading; nested details appear there as plain dicts, and a detail that is None is absent.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from ..jsonable import plain


class Details(Mapping[str, Any]):
    """Base of the typed details: a read-only mapping of :meth:`named`, equal to any mapping with the same
    items."""

    __slots__ = ()

    def named(self) -> dict[str, Any]:
        """The details by the names of the dict they replace (units in the names), nested details as dicts."""
        raise NotImplementedError

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy of :meth:`named` (non-finite numbers as None)."""
        return plain(self.named())

    def __getitem__(self, name: str) -> Any:
        return self.named()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.named())

    def __len__(self) -> int:
        return len(self.named())


def _present(pairs: dict[str, Any]) -> dict[str, Any]:
    """``pairs`` without the None values, nested details as dicts."""
    return {k: v.named() if isinstance(v, Details) else v for k, v in pairs.items() if v is not None}


@dataclass(frozen=True, kw_only=True, eq=False)
class SlowErrors(Details):
    """The channels' slow errors estimated with the answer, and how far they move it."""

    #: offset b of δ'' [m/s²]
    offset: float
    #: drift b' of δ'' [m/s³]
    drift: float
    #: the answer's V0 [m/s] and w = 1/M1 [1/kg] without them minus with them
    shift_velocity: float
    shift_inverse_mass: float

    def named(self) -> dict[str, Any]:
        return {"offset_m_s2": self.offset, "drift_m_s3": self.drift, "shift_v0_m_s": self.shift_velocity,
                "shift_w_1_kg": self.shift_inverse_mass}


@dataclass(frozen=True, kw_only=True, eq=False)
class ModelError(Details):
    """Standard deviation of the model error added to the rows that rest on a contact model."""

    #: of the turning points' rows [m/s]
    extrema: float
    #: of the separations' rows [m]
    separations: float

    def named(self) -> dict[str, Any]:
        return {"extrema_m_s": self.extrema, "separations_m": self.separations}


@dataclass(frozen=True, kw_only=True, eq=False)
class Nuisances(Details):
    """The nuisances estimated with (V0, w); None where not estimated."""

    #: lag λe of the turning points [s]
    lag_e: float | None = None
    #: lag λs of the separations [s]
    lag_s: float | None = None
    #: set fraction μ of the separations [-]
    set_fraction: float | None = None
    #: residual offset b of the acceleration after the pre-trigger correction [m/s²]
    offset: float | None = None
    slow_errors: SlowErrors | None = None
    model_error: ModelError | None = None

    def named(self) -> dict[str, Any]:
        return _present({"lag_e": self.lag_e, "lag_s": self.lag_s, "set": self.set_fraction,
                         "offset_m_s2": self.offset, "slow_errors": self.slow_errors,
                         "model_error": self.model_error})


@dataclass(frozen=True, kw_only=True, eq=False)
class RowsUsed(Details):
    """The rows an answer used, by kind."""

    onsets: int = 0
    extrema: int = 0
    stage_b_extrema: int = 0
    separations: int = 0
    #: samples between the first and the last turning point in sustained contact
    stage_b_samples: int = 0

    def named(self) -> dict[str, Any]:
        return {"onsets": self.onsets, "extrema": self.extrema, "stage_b_extrema": self.stage_b_extrema,
                "separations": self.separations, "stage_b_samples": self.stage_b_samples}


@dataclass(frozen=True, kw_only=True, eq=False)
class GapReadings(Details):
    """The answer where the gaps between the pulses read as flights and as a contact that kept a set, where the
    data fit both alike: (V0 [m/s], M1 [kg]) of each."""

    flights: tuple[float, float]
    kept_set: tuple[float, float]

    def named(self) -> dict[str, Any]:
        return {"flights": self.flights, "set": self.kept_set}


@dataclass(frozen=True, kw_only=True, eq=False)
class EquationsUsed(Details):
    """What a robust peak-to-peak answer used: its rows, the nuisances estimated with it, the two readings of the
    gaps (where the data cannot tell them apart) and the contact-phase fit (where it joined)."""

    rows: RowsUsed
    nuisances: Nuisances | None = None
    gap_readings: GapReadings | None = None
    #: the contact-phase fit's account (:class:`.peak_to_peak.early.ContactFit` ``info``, and ``combined``)
    contact_phase: Mapping[str, Any] | None = None

    @property
    def turning_scatter(self) -> float:
        """Standard deviation of the turning points' model error [m/s] (0 where none was estimated)."""
        found = self.nuisances.model_error if self.nuisances is not None else None
        return found.extrema if found is not None else 0.0

    def named(self) -> dict[str, Any]:
        return {**self.rows.named(), **(self.nuisances.named() if self.nuisances is not None else {}),
                **_present({"gap_readings": self.gap_readings,
                            "contact_phase": None if self.contact_phase is None else dict(self.contact_phase)})}


@dataclass(frozen=True, kw_only=True, eq=False)
class PeakToPeakDetails(Details):
    """What a peak-to-peak answer used: the instants it read, its stage and equations, its fit."""

    #: first contact and the force peaks of the first two pulses [s] (NaN: not reached)
    t00: float
    t01: float = math.nan
    t11: float = math.nan
    #: contact onsets found [s]: t00 and the onset of every later pulse (robust; empty for the paper variant)
    onsets: tuple[float, ...] = ()
    #: ``early`` or ``final`` (robust)
    stage: str | None = None
    equations: EquationsUsed | None = None
    #: chi-square and degrees of freedom of the fit (robust)
    chi2: float | None = None
    dof: int | None = None
    #: white-noise standard deviations of the channels [N], [m/s²]
    noise_force: float | None = None
    noise_acceleration: float | None = None
    #: samples of the pre-trigger the offsets were removed with (robust)
    pre_trigger_samples: int | None = None
    #: why the answer deserves caution (filtered channels, noise beyond the paper variant's limit)
    caution: str | None = None

    @classmethod
    def from_mapping(cls, details: Mapping[str, Any]) -> PeakToPeakDetails:
        """The typed form of a peak-to-peak details dict (the names of :meth:`named`)."""
        return cls(t00=details["t00"], t01=details.get("t01", math.nan), t11=details.get("t11", math.nan),
                   onsets=tuple(details.get("onsets", ())), stage=details.get("stage"),
                   chi2=details.get("chi2"), dof=details.get("dof"), noise_force=details.get("noise_force_N"),
                   noise_acceleration=details.get("noise_acceleration_m_s2"),
                   pre_trigger_samples=details.get("pre_trigger_samples"), caution=details.get("caution"))

    @property
    def agnostic(self) -> bool:
        """Whether the answer came from the agnostic equations (onsets, turning points, separations), whose χ²
        measures the fit to the noise, rather than from the contact-phase fit."""
        used = self.equations
        return self.stage == "final" and used is not None and used.contact_phase is None and (
            used.rows.onsets >= 1 or used.rows.stage_b_extrema >= 1)

    def named(self) -> dict[str, Any]:
        return _present({"t00": self.t00, "t01": self.t01, "t11": self.t11, "onsets": self.onsets,
                         "stage": self.stage, "equations": self.equations, "chi2": self.chi2, "dof": self.dof,
                         "noise_force_N": self.noise_force, "noise_acceleration_m_s2": self.noise_acceleration,
                         "pre_trigger_samples": self.pre_trigger_samples, "caution": self.caution})


@dataclass(frozen=True, kw_only=True, eq=False)
class ResponseMapDetails(Details):
    """What a response-map answer used."""

    #: eq. (7) at the answer [-]
    residual: float
    #: feature name -> measured value
    features: Mapping[str, float]
    feature_set: str
    #: the pressure the map was read at [Pa gauge]
    pressure_gauge: float
    #: the answer lies outside the map
    extrapolated: bool

    def named(self) -> dict[str, Any]:
        return {"residual": self.residual, "features": dict(self.features), "feature_set": self.feature_set,
                "pressure_gauge": self.pressure_gauge, "extrapolated": self.extrapolated}


@dataclass(frozen=True, kw_only=True, eq=False)
class StreamStage(Details):
    """Where in a model stream an answer was given."""

    #: ``first``, ``update`` or ``final``
    stage: str
    #: record between updates [s]
    cadence: float
    #: record read after first contact [s]
    window: float
    #: which contact law the stream follows and why
    law_choice: str
    #: what the σ assumes of the stand (before the stand is freed)
    sigma_given: str | None = None
    #: processor time of the answer [s]
    update_time: float | None = None

    def named(self) -> dict[str, Any]:
        return _present({"stage": self.stage, "cadence_s": self.cadence, "window_ms": self.window * 1e3,
                         "law_choice": self.law_choice, "sigma_given": self.sigma_given,
                         "update_time_s": self.update_time})


@dataclass(frozen=True, kw_only=True, eq=False)
class Adequacy(Details):
    """Whether the stand model explains the record down to its noise, and the path the answer took
    (:mod:`~impactometer.identify.model_fit.adequacy`): ``adequate`` (the Fisher σ), ``widened`` (the sandwich σ
    of a model that leaves correlated residuals) or ``fell back`` (the robust answer, the model's answer
    disagreeing with it), and why."""

    verdict: str
    reason: str
    #: χ²/dof of the fit and the largest z of the channels' misfit (mean squared residual after contact against the
    #: pre-trigger's noise) [-]
    reduced_chi2: float | None = None
    chi2_z: float | None = None
    #: mean squared weighted residual after contact of the force and the acceleration [-]
    misfit: tuple[float, float] | None = None
    #: the larger lag-1 autocorrelation of the channels' weighted residuals after contact and its z against the
    #: pre-trigger's [-]
    autocorrelation: float | None = None
    autocorrelation_z: float | None = None
    #: samples per channel after contact and of the pre-trigger
    samples: int | None = None
    pre_trigger_samples: int | None = None
    #: the sandwich's bandwidth [samples] and its σ over the Fisher σ of M1 and V0 (``widened``)
    bandwidth: int | None = None
    widening: tuple[float, float] | None = None
    #: the larger difference of M1 or V0 to the robust answer over their joint σ [-]
    robust_z: float | None = None
    #: the factor sqrt(χ²/dof) the robust answer's σ is widened by where its rows scatter beyond their noise
    #: (``fell back``) [-]
    robust_inflation: float | None = None
    #: the difference of the fit of the first span after contact and the whole record's fit over its σ, in M1 and
    #: V0 (the specification test, :func:`~impactometer.identify.model_fit.adequacy._nested`) [-]
    nested_z: tuple[float, float] | None = None

    def named(self) -> dict[str, Any]:
        return _present({"verdict": self.verdict, "reason": self.reason, "chi2_dof": self.reduced_chi2,
                         "chi2_z": self.chi2_z, "misfit": None if self.misfit is None else list(self.misfit),
                         "autocorrelation": self.autocorrelation, "autocorrelation_z": self.autocorrelation_z,
                         "samples": self.samples, "pre_trigger_samples": self.pre_trigger_samples,
                         "bandwidth_samples": self.bandwidth,
                         "widening": None if self.widening is None else list(self.widening),
                         "robust_z": self.robust_z, "robust_inflation": self.robust_inflation,
                         "nested_z": None if self.nested_z is None else list(self.nested_z)})


@dataclass(frozen=True, kw_only=True, eq=False)
class ModelDetails(Details):
    """What a model answer used: the fit's path (``ml``: the fit's answer; ``fallback``: the robust answer, the
    model not describing the record) and why, the contact law chosen and every law's fit, where the fit started,
    the robust answer, the noise and the fit's figures. A fall-back carries the robust answer's own typed details
    (``fallback``); its mapping holds both."""

    path: str
    reason: str
    contact_law: str | None
    #: the rule the contact law was chosen by, and law -> its fit's figures (or why it failed or was dropped)
    criterion: str | None = None
    model_selection: Mapping[str, Any] | None = None
    #: where the fit started (``mass_kg``, ``velocity_m_s``, ``contact_time_s``, ``from``)
    start: Mapping[str, Any] | None = None
    #: the robust answer (``mass_kg``, ``velocity_m_s`` and their σ) or why it failed (``error``)
    robust: Mapping[str, Any] | None = None
    #: noise σ of the channels [N], [m/s²] and the anti-alias design the model reproduced
    noise_force: float | None = None
    noise_acceleration: float | None = None
    anti_alias: str | None = None
    #: the fit's first contact [s], χ²/dof, χ², degrees of freedom
    t00: float | None = None
    reduced_chi2: float | None = None
    chi2: float | None = None
    dof: int | None = None
    #: Cramér-Rao σ of M1 and V0 at the estimate (the bound's mapping)
    crb: Mapping[str, Any] | None = None
    #: the span of the record after first contact the fit read [s] and why it ends there
    fit_span: float | None = None
    fit_span_reason: str | None = None
    #: fitted stand parameter -> value [SI] and its σ
    parameters: Mapping[str, Any] | None = None
    #: the calibrated stand's stated uncertainty carried into σ(M1), σ(V0): the parameters and the σ they add
    stand_uncertainty: Mapping[str, Any] | None = None
    #: on fall-back, the details of the robust answer given
    fallback: Mapping[str, Any] | None = None
    #: in a stream, where the answer was given
    stream: StreamStage | None = None
    #: the model-adequacy test and the path the answer took
    adequacy: Adequacy | None = None
    #: for a record that names no stand, identified without one: the built-in stands compared (each one's best law,
    #: BIC and ΔBIC to the default over common samples), the threshold and which explains the record better
    stands: Mapping[str, Any] | None = None

    def named(self) -> dict[str, Any]:
        base = {} if self.fallback is None else (
            self.fallback.named() if isinstance(self.fallback, Details) else dict(self.fallback))
        own = {"model_selection": self.model_selection, "criterion": self.criterion, "start": self.start,
               "robust": self.robust, "noise_force_N": self.noise_force,
               "noise_acceleration_m_s2": self.noise_acceleration, "anti_alias": self.anti_alias,
               "path": self.path, "reason": self.reason, "t00": self.t00, "reduced_chi2": self.reduced_chi2,
               "chi2": self.chi2, "dof": self.dof, "crb": self.crb, "fit_span_s": self.fit_span,
               "fit_span": self.fit_span_reason, "parameters": self.parameters,
               "stand_uncertainty": self.stand_uncertainty, "adequacy": self.adequacy,
               "stands": self.stands}
        return {**base, **_present(own), "contact_law": self.contact_law,
                **({} if self.stream is None else self.stream.named())}
