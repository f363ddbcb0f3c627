"""``impactometer identify`` and ``impactometer stream``: identify M1 and V0 from a recorded file."""

from __future__ import annotations

import json
import time as clock
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.markup import escape
from rich.table import Table

from ..errors import IdentificationError, ParameterError
from ..outputs import save_figure
from ..units import parse_quantity
from .app import OVERWRITE, announce_compilation, app, console, given, output_path, quantity, with_uncertainty
from .reading import DEFAULT_READER, ReaderOptions, reader_options

# the identification modules load numba: they are imported where they are used, so that ``--help`` stays light
if TYPE_CHECKING:
    from ..identify.result import Identification

METHODS = ("peak-to-peak", "response-map", "model")
VariantOpt = Annotated[str, typer.Option("--variant", metavar="NAME", help="robust (default) or paper.")]
ContactOpt = Annotated[bool, typer.Option("--contact-phase", help="robust: add the contact-phase fit of the first "
                                                                   "two pulses to the final answer.")]


def _row(table: Table, label: str, value: float | None, std: float | None, unit: str) -> None:
    if value is not None:
        table.add_row(label, with_uncertainty(value, std, unit))


def _table(result: dict, title: str) -> Table:
    table = Table(title=title, show_header=False)
    table.add_column("quantity", no_wrap=True)
    table.add_column("value")
    for key, sub in (("final", result), ("early", result.get("early"))):
        if not sub:
            continue
        prefix = "" if key == "final" else "early: "
        _row(table, prefix + "mass M1", sub["mass_kg"], sub.get("mass_std_kg"), "kg")
        _row(table, prefix + "velocity V0", sub["velocity_m_s"], sub.get("velocity_std_m_s"), "m/s")
        _row(table, prefix + "energy", sub["energy_J"], sub.get("energy_std_J"), "J")
        if sub.get("available_at_s") is not None:
            table.add_row(prefix + "available at", f"{sub['available_at_s'] * 1e3:.3f} ms")
        if sub.get("equations"):
            table.add_row(prefix + "equations", equations_text(sub["equations"]))
    if not result.get("early") and result.get("early_reason"):
        table.add_row("early", escape(f"none: {result['early_reason']}"))
    for key in ("t00_s", "t01_s", "t11_s"):
        if result.get(key) is not None:
            table.add_row(key[:-2], f"{result[key] * 1e3:.3f} ms")
    if result.get("caution"):
        table.add_row("caution", result["caution"])
    for warning in result.get("warnings") or ():
        table.add_row("warning", escape(warning))
    return table


def equations_text(used: dict) -> str:
    """One line naming the equations an answer used."""
    text = (f"{used.get('onsets', 0)} onsets, {used.get('extrema', 0)} force extrema "
            f"({used.get('stage_b_extrema', 0)} in stage B over {used.get('stage_b_samples', 0)} samples), "
            f"{used.get('separations', 0)} separations")
    if used.get("contact_phase"):
        text += f", contact phase ({used['contact_phase'].get('samples', 0)} samples)"
    return text


@app.command()
@reader_options
def identify(file: Annotated[Path, typer.Argument(metavar="FILE", help="Recording (csv, h5, tdms, mat).")],
             method: Annotated[str, typer.Option("--method", metavar="NAME",
                                                 help="peak-to-peak, response-map or model.")] = "peak-to-peak",
             variant: VariantOpt = "robust",
             contact_phase: ContactOpt = False,
             map_path: Annotated[Path | None, typer.Option("--map", metavar="FILE", help="Response map (.h5).")]
             = None,
             search: Annotated[str, typer.Option("--search", metavar="NAME", help="Map search: fast or brute.")]
             = "fast",
             allow_extrapolation: Annotated[bool, typer.Option(
                 "--allow-extrapolation",
                 help="response-map: answer outside the map's grid (else an error).")] = False,
             rig: Annotated[str | None, typer.Option("--rig", metavar="STAND", help="model: the stand, a preset name "
                                                                                 "or a TOML file.")] = None,
             pressure: Annotated[str | None, typer.Option(
                 "--pressure", metavar="PRESSURE",
                 help="response-map, model: charge pressure p0, gauge (e.g. 200kPa); else the file's statement "
                      "(model: else fitted).")] = None,
             pressure_std: Annotated[str | None, typer.Option(
                 "--pressure-std", metavar="SIGMA",
                 help="model: σ of the stated charge pressure (e.g. 4kPa, or 2% of it); default 2% of the reading, "
                      "at least 1kPa (0: held exactly).")] = None,
             as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
             plot: Annotated[Path | None, typer.Option("--plot", metavar="FILE",
                                                       help="Save a figure of the instants used.")] = None,
             overwrite: Annotated[bool, typer.Option(*OVERWRITE, help="Overwrite the --plot file.")] = False,
             reader: ReaderOptions = DEFAULT_READER) -> None:
    """Identify the impacting mass and velocity of the first impact in FILE."""
    if method not in METHODS:
        raise ParameterError(f"--method must be one of {list(METHODS)}, got {method!r}")
    if plot is not None and method != "peak-to-peak":
        raise ParameterError("--plot is available for --method peak-to-peak")
    if pressure is not None and method == "peak-to-peak":
        raise ParameterError("--pressure is an option of --method response-map and --method model")
    if rig is not None and method != "model":
        raise ParameterError("--rig is an option of --method model")
    if pressure_std is not None and method != "model":
        raise ParameterError("--pressure-std is an option of --method model")
    pressure_gauge = quantity(pressure, "pressure", "--pressure")
    output_path(plot, overwrite, field="--plot", kind="figure")
    rec = reader.read(file)
    result: Identification
    if method == "response-map":
        if map_path is None:
            raise ParameterError("--method response-map needs --map FILE "
                                 "(a response map built with impactometer map build)")
        from ..identify.response_map import identify_recording

        with given(search=search, pressure=pressure), announce_compilation("searching the response map"):
            result = identify_recording(rec, map_path, search=search, allow_extrapolation=allow_extrapolation,
                                        pressure_gauge=pressure_gauge)
    elif method == "model":
        from ..identify.model_fit import identify as identify_model

        gauge_std = _pressure_std(pressure_std, pressure_gauge, rec.metadata.get("pressure_gauge_Pa"))
        with given(rig=rig, pressure=pressure, pressure_std=pressure_std), \
                announce_compilation("fitting the stand model to the record", compile_time="about 10-40 s"):
            result = identify_model(rec, rig=rig, pressure_gauge=pressure_gauge, pressure_gauge_std=gauge_std)
    else:
        from ..identify.peak_to_peak import identify as identify_p2p

        with given(variant=variant), announce_compilation("identifying M1 and V0", compile_time="about 5-20 s"):
            result = identify_p2p(rec, variant=variant, contact_phase=contact_phase)
    from .app import speak_text

    data = result.to_dict()
    data["warnings"] = [speak_text(warning, {"rig": rig, "pressure": pressure,
                                                         "pressure_std": pressure_std}) for warning in data["warnings"]]
    if as_json:
        typer.echo(json.dumps(data))
    else:
        detail = data.get("variant") or f"{data.get('feature_set', '')}, {data.get('search', '')} search"
        if data.get("contact_law"):
            detail += f", {data['contact_law']} contact"
        console.print(_table(data, f"{file.name}: {method} ({detail})"))
    if plot is not None:
        from ..identify.peak_to_peak import used_samples

        save_figure(result.plot(rec, used=used_samples(result, rec)), plot)
        if not as_json:
            console.print(f"figure written to {plot}")


STREAM_METHODS = ("peak-to-peak", "model")


@app.command()
@reader_options
def stream(file: Annotated[Path, typer.Argument(metavar="FILE", help="Recording to replay.")],
           method: Annotated[str, typer.Option("--method", metavar="NAME", help="peak-to-peak (default) or model: "
                                                                                 "the stand model's updates.")]
           = "peak-to-peak",
           variant: VariantOpt = "robust",
           contact_phase: ContactOpt = False,
           cadence: Annotated[str | None, typer.Option(
               "--cadence", metavar="TIME", help="model: record between updates (default 10ms).")] = None,
           first: Annotated[str | None, typer.Option(
               "--first", metavar="TIME", help="model: record after first contact the first answer reads "
                                               "(default 4ms).")] = None,
           rig: Annotated[str | None, typer.Option("--rig", metavar="STAND", help="model: the stand, a preset name "
                                                                               "or a TOML file.")] = None,
           pressure: Annotated[str | None, typer.Option(
               "--pressure", metavar="PRESSURE", help="model: charge pressure p0, gauge (e.g. 200kPa); else the "
                                                      "file's statement, else fitted.")] = None,
           chunk: Annotated[int, typer.Option("--chunk", metavar="SAMPLES", help="Samples per push.")] = 64,
           realtime: Annotated[bool, typer.Option("--realtime", help="Replay at the file's sample rate.")] = False,
           as_json: Annotated[bool, typer.Option("--json", help="One JSON object per estimate, its stage (early, "
                                                                "first, update or final) named.")] = False,
           reader: ReaderOptions = DEFAULT_READER) -> None:
    """Replay FILE through the streaming identifier and print each estimate with the time it became available."""
    if method not in STREAM_METHODS:
        raise ParameterError(f"--method must be one of {list(STREAM_METHODS)}, got {method!r}")
    if method != "model" and (cadence, first, rig, pressure) != (None, None, None, None):
        raise ParameterError("--cadence, --first, --rig and --pressure are options of --method model")
    if chunk < 1:
        raise ParameterError(f"--chunk must be >= 1 [samples], got {chunk}")
    if method == "model":
        from ..identify.model_fit.streaming import check_schedule

        durations = {"cadence": quantity(cadence, "time", "--cadence"), "first": quantity(first, "time", "--first")}
        with given(cadence=cadence, first=first):  # before the file is read
            check_schedule(**{name: value for name, value in durations.items() if value is not None})
        _stream_model(file, reader.read(file), durations, {"cadence": cadence, "first": first, "rig": rig,
                                                            "pressure": pressure}, chunk, realtime, as_json)
        return
    rec = reader.read(file)
    from ..identify.peak_to_peak import check_unfiltered
    from ..identify.peak_to_peak.streaming import StreamingIdentifier

    with given(variant=variant):
        check_unfiltered(rec, variant)
        ident = StreamingIdentifier(rec.sample_rate, variant=variant, start_time=rec.start_time,
                                    contact_phase=contact_phase)
    concluded = 0

    def report(new: list, at: float, took: float) -> None:
        nonlocal concluded
        concluded = _report(ident, new, concluded, at, as_json)

    _replay(rec, ident, chunk, realtime, report)
    shown = len(ident.estimates)
    final = ident.finish()  # raises the refusal of the last impact
    _report(ident, ident.estimates[shown:], concluded, rec.start_time + rec.contact_force.size / rec.sample_rate,
            as_json)
    if final is None:
        raise IdentificationError("no estimate: the stream holds no impact with enough contact pulses")
    if not as_json:
        console.print(_table(final.to_dict(), f"{file.name}: final answer of the stream ({variant})"))


def _replay(rec, ident, chunk: int, realtime: bool, report) -> None:
    """Push the recording through ``ident`` in chunks (at the file's pace with ``realtime``), reporting each push's
    estimates with the time of its last sample [s] and the processor time the push took on this thread [s]."""
    f, a = rec.contact_force, rec.piston_acceleration
    t_wall = clock.perf_counter()
    # a line on standard error if the first impact compiles the kernels; estimates print as they come
    with announce_compilation("streaming", compile_time="about 5-40 s", spinner=False):
        for k in range(0, f.size, chunk):
            if realtime:
                lag = k / rec.sample_rate - (clock.perf_counter() - t_wall)
                if lag > 0:
                    clock.sleep(lag)
            busy = clock.thread_time()
            new = ident.push(f[k:k + chunk], a[k:k + chunk])
            report(new, rec.start_time + min(k + chunk, f.size) / rec.sample_rate, clock.thread_time() - busy)


def _stream_model(file: Path, rec, durations: dict, texts: dict, chunk: int, realtime: bool, as_json: bool) -> None:
    """``stream --method model``: the model's first answer, its updates every cadence and the final answer, each
    with the wall time it took; a closing line with the median and 90th percentile of the updates' times.
    ``durations``: ``cadence`` and ``first`` [s] as given (None: the defaults); ``texts``: the options as the user
    wrote them (``cadence``, ``first``, ``rig``, ``pressure``)."""
    import numpy as np

    from ..identify.model_fit.engine import check_length
    from ..identify.model_fit.streaming import ModelStream
    from .app import error_console

    given_times = {name: value for name, value in durations.items() if value is not None}
    with given(**texts):
        ident = ModelStream(rec.sample_rate, start_time=rec.start_time, metadata=rec.metadata, rig=texts["rig"],
                            pressure_gauge=quantity(texts["pressure"], "pressure", "--pressure"), **given_times)
    check_length(rec)  # the final answer's record, before any estimate is printed

    behind = False

    def report(new: list, at: float, took: float) -> None:
        nonlocal behind
        for est in new:
            _print_estimate(est, est.details.get("stage", "update"), as_json)
        if not behind and took > ident.cadence and any(est.details.get("stage") == "update" for est in new):
            behind = True  # said once
            error_console.print(f"note: an update took {took * 1e3:.3g} ms of processor time, more than the cadence "
                                f"of {ident.cadence * 1e3:g} ms: live, this stream would fall behind its cadence on "
                                "this machine (a longer --cadence keeps up)", highlight=False, markup=False,
                                soft_wrap=True)

    _replay(rec, ident, chunk, realtime, report)
    shown = len(ident.estimates)
    final = ident.finish()  # raises the refusal of the last impact
    report(ident.estimates[shown:], 0.0, 0.0)
    if final is None:
        raise IdentificationError("no estimate: the stream holds no impact")
    times = np.array([est.details["update_time_s"] for est in ident.estimates if est.details.get("stage") == "update"])
    median, p90 = (float(np.median(times)), float(np.percentile(times, 90))) if times.size else (None, None)
    if as_json:
        typer.echo(json.dumps({"kind": "summary", "cadence_s": ident.cadence, "updates": int(times.size),
                               "update_time_median_s": median, "update_time_p90_s": p90,
                               "first_available_at_s": ident.estimates[0].available_at if ident.estimates else None}))
        return
    if median is not None and p90 is not None:
        console.print(f"{times.size} updates every {ident.cadence * 1e3:g} ms of record; time per update: median "
                      f"{median * 1e3:.2f} ms, 90th percentile {p90 * 1e3:.2f} ms (this machine, one process)",
                      highlight=False)
    data = final.to_dict()
    console.print(_table(data, f"{file.name}: final answer of the stream (model, {data.get('contact_law')} contact)"))


def _print_refusal(error: IdentificationError, at: float, as_json: bool) -> None:
    if as_json:
        typer.echo(json.dumps({"kind": "refused", "available_at_s": at, "error": str(error)}))
    else:
        console.print(f"t = {at * 1e3:9.3f} ms  refused  {' '.join(str(error).split())}", highlight=False,
                      markup=False, soft_wrap=True)


def _report(ident, new: list, concluded: int, at: float, as_json: bool) -> int:
    """Print the estimates ``new`` of a push and the impacts concluded since the outcome ``concluded``: a refusal
    (as identify refuses it) and, in JSON, a final answer the identifier did not repeat because an update had
    already given it. Returns the number of outcomes now reported."""
    for est in new:
        _print_estimate(est, _stage(est, ident), as_json)
    for outcome in ident.outcomes[concluded:]:
        if isinstance(outcome, IdentificationError):
            _print_refusal(outcome, at, as_json)
        elif as_json and not any(outcome is est for est in new):
            _print_estimate(outcome, "final", as_json)
    return len(ident.outcomes)


def _stage(est, ident) -> str:
    """``early`` (the contact-phase answer of the first two pulses), ``final`` (the answer of a concluded impact)
    or ``update`` (an answer the rest of the impact may still refine)."""
    if est.details.get("stage") == "early":
        return "early"
    return "final" if any(est is done for done in ident.completed) else "update"


def _print_estimate(est, stage: str, as_json: bool) -> None:
    d = est.to_dict()
    kind = "early" if stage == "early" else "estimate"
    took = est.details.get("update_time_s")
    if as_json:
        d["kind"] = kind
        d["stage"] = stage
        if took is not None:  # the model stream's own figures
            d.update(update_time_s=took, cadence_s=est.details.get("cadence_s"), window_ms=est.details.get("window_ms"),
                     law_choice=est.details.get("law_choice"), sigma_given=est.details.get("sigma_given"))
        typer.echo(json.dumps(d))
        return
    model = "" if took is None else (f"  [{stage}, {est.details.get('window_ms', float('nan')):.3g} ms after contact, "
                                     f"{est.details.get('contact_law')}, chi2/dof "
                                     f"{est.details.get('reduced_chi2', float('nan')):.3g}, took {took * 1e3:.1f} ms]")
    console.print(f"t = {est.available_at * 1e3:9.3f} ms  {kind:8s} "
                  f"M1 = {with_uncertainty(est.mass, est.mass_std, 'kg')}  "
                  f"V0 = {with_uncertainty(est.velocity, est.velocity_std, 'm/s')}  E = {est.energy:.1f} J{model}",
                  highlight=False, markup=False, soft_wrap=True)
    for warning in est.warnings:
        console.print(f"{'':15s}warning: {warning}", highlight=False, markup=False, soft_wrap=True)


def _pressure_std(text: str | None, pressure: float | None, stated: object) -> float | None:
    """``--pressure-std`` in Pa: a pressure (``4kPa``, bare Pa) or a percentage of the stated pressure (``2%``:
    of ``--pressure``, else of the file's ``pressure_gauge_Pa``); None passes through."""
    if text is None or not text.strip().endswith("%"):
        return None if text is None else parse_quantity(text, "pressure", field="--pressure-std")
    fraction = parse_quantity(text, "fraction", field="--pressure-std")
    try:
        base = float(pressure if pressure is not None else stated)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ParameterError(f"--pressure-std {text}: a percentage needs a stated pressure (--pressure, or the "
                             "file's pressure_gauge_Pa); give it in Pa or kPa") from None
    return fraction * abs(base)
