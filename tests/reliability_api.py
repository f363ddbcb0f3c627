"""Random bad arguments thrown at the public Python functions: each call returns or raises an ImpactometerError.

A call that raises anything else (TypeError, ValueError, OverflowError, IndexError, ...) is unhandled. The calls are
drawn from a fixed seed, so a run is reproducible.
"""

from __future__ import annotations

import random
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from impactometer.control.strategies import strategy_names
from impactometer.errors import ImpactometerError
from impactometer.filters import cfc_corridor, filter_recording
from impactometer.identify.inspection import inspect_recording
from impactometer.identify.model_fit import cramer_rao
from impactometer.identify.model_fit import identify as identify_model
from impactometer.identify.model_fit.streaming import ModelStream
from impactometer.identify.peak_to_peak import identify, identify_arrays
from impactometer.identify.peak_to_peak.streaming import StreamingIdentifier, stream_arrays
from impactometer.identify.plausibility import check_answer
from impactometer.identify.response_map import (
    build_map_from_recordings,
    build_map_simulated,
    identify_features,
    identify_recording,
    load_map,
    refine,
    save_map,
)
from impactometer.identify.response_map.features import get_feature_set
from impactometer.io import read_calibration_set, read_recording, write_recording
from impactometer.model import simulate_batch
from impactometer.recording import Recording
from impactometer.rig import Scenario, from_dict, get_rig, load_toml, save_toml
from impactometer.sensors import apply_sensors, record
from impactometer.signals.noise import robust_noise_std
from impactometer.studies import StudyOptions, get_study, run_study
from impactometer.units import parse_quantity

BAD = [None, "abc", "", -1, 0, 1e308, -1e308, float("nan"), float("inf"), np.float64(3.0), np.int64(-2), True, [],
       [1, 2], {}, {"a": 1}, np.arange(3.0), np.array([np.nan]), object(), 1 + 2j, b"x", np.zeros((2, 2)), 2**70,
       -0.0, 1e-320]


def calls(recording: Recording, path: Path, map_path: Path, folder: Path) -> dict[str, Callable]:
    """Public functions, each taking two arguments ``x`` and ``y`` where it takes user input (``path``: the
    recording's file; names given as text are taken inside ``folder``)."""
    rmap = load_map(map_path)
    f, a = recording.contact_force, recording.piston_acceleration
    scenario = Scenario(mass=30.0, velocity=2.0)
    short = Recording(sample_rate=5e4, channels={"contact_force": np.zeros(10), "piston_acceleration": np.zeros(10)})
    out = folder / "api"
    out.mkdir(exist_ok=True)
    return {
        "Recording": lambda x, y: Recording(sample_rate=x, channels={"contact_force": y}),
        "Recording channels": lambda x, y: Recording(sample_rate=5e4, channels=x, start_time=y),
        "Recording truth": lambda x, y: Recording(sample_rate=5e4, channels={"f": [1.0, 2.0]},
                                                  metadata={"mass_kg": x, "velocity_m_s": y}),
        "Recording.from_time": lambda x, y: Recording.from_time(x, {"contact_force": y}),
        "identify_arrays": lambda x, y: identify_arrays(x, y, 5e4),
        "identify_arrays rate": lambda x, y: identify_arrays(f, a, x, y),
        "identify_arrays options": lambda x, y: identify_arrays(f, a, 5e4, variant=x, gravity=y),
        "identify": lambda x, y: identify(x, variant=y),
        "StreamingIdentifier": lambda x, y: StreamingIdentifier(x, start_time=y),
        "StreamingIdentifier.push": lambda x, y: StreamingIdentifier(5e4).push(x, y),
        # a record too short for the model fit: its options are checked, then the record is refused
        "model_fit.identify": lambda x, y: identify_model(short, uncertain=x, pressure_gauge=y),
        "model_fit.cramer_rao": lambda x, y: cramer_rao(short, at=x, mass=y),
        "ModelStream": lambda x, y: ModelStream(5e4, metadata=x, cadence=y),
        "stream_arrays": lambda x, y: stream_arrays(f, a, 5e4, chunk=x, variant=y),
        "identify_features": lambda x, y: identify_features(x, rmap, pressure_gauge=y),
        "identify_features options": lambda x, y: identify_features([5000.0, 20.0], rmap, search=x, available_at=y),
        "identify_recording": lambda x, y: identify_recording(x, rmap, search=y),
        "refine": lambda x, y: refine(rmap, x),
        "build_map_simulated": lambda x, y: build_map_simulated(None, 200e3, masses=x, velocities=[1.0, 2.0],
                                                                sample_rate=5e4 if y is None else y),
        "build_map_from_recordings": lambda x, y: build_map_from_recordings(x, grid=y),
        "load_map": lambda x, y: load_map(x),
        "save_map": lambda x, y: save_map(rmap, out / x if isinstance(x, str) else x, overwrite=y),
        "record": lambda x, y: record(scenario, sample_rate=x, duration=y),
        "record noise": lambda x, y: record(scenario, noise=x, seed=y),
        "record ADC": lambda x, y: record(scenario, adc_bits=x, pre_trigger=y),
        "record filter": lambda x, y: record(scenario, anti_alias=x, adc_range=y),
        "apply_sensors": lambda x, y: apply_sensors(recording, sample_rate=x, noise=y),
        "Scenario": lambda x, y: Scenario(mass=x, velocity=y),
        "get_rig": lambda x, y: get_rig(x, contact=y),
        "from_dict": lambda x, y: from_dict({"cylinder": {"bore": x}, "gravity": y}),
        "Rig.replace": lambda x, y: get_rig().replace(**{"cylinder.stroke": x, "stops.stiffness": y}),
        "Rig.with_contact": lambda x, y: get_rig().with_contact(x),
        "filter_recording": lambda x, y: filter_recording(recording if y is None else y, x),
        "filter_recording standard": lambda x, y: filter_recording(recording, 60, standard=x),
        "parse_quantity": lambda x, y: parse_quantity(x, "mass" if y is None else y),
        "inspect_recording": lambda x, y: inspect_recording(x),
        "read_recording": lambda x, y: read_recording(x),
        "read_recording options": lambda x, y: read_recording(path, force_channel=x, sample_rate=y),
        "write_recording": lambda x, y: write_recording(recording, out / x if isinstance(x, str) else x, overwrite=y),
        "read_calibration_set": lambda x, y: read_calibration_set(x, y),
        "get_feature_set": lambda x, y: get_feature_set(x),
        "get_study": lambda x, y: get_study(x),
        "StudyOptions": lambda x, y: StudyOptions(grid=x, noise=0.01 if y is None else y),
        "StudyOptions settings": lambda x, y: StudyOptions(params={"noise.levels": x} if y is None else x),
        "strategy_names": lambda x, y: strategy_names(x),
        "check_answer": lambda x, y: check_answer(x, y),
        "robust_noise_std": lambda x, y: robust_noise_std(x),
        "simulate_batch": lambda x, y: simulate_batch(x, 2.0, 200e3, duration=0.002 if y is None else y),
        "cfc_corridor": lambda x, y: cfc_corridor(60 if y is None else y, x),
        "save_toml": lambda x, y: save_toml(get_rig() if y is None else x, out / x if isinstance(x, str) else x,
                                            overwrite=True),
        "load_toml": lambda x, y: load_toml(x),
        # a text names a folder in which the study would run: only the other values are thrown at it
        "run_study": lambda x, y: run_study("peak-force", None if isinstance(x, str) else x, StudyOptions(grid=2)),
        "Recording.channel": lambda x, y: recording.channel(x),
    }


def fuzz(table: dict[str, Callable], count: int, seed: int = 0) -> tuple[int, list[str]]:
    """Make ``count`` random calls; (calls made, one line per distinct unhandled failure)."""
    rng = random.Random(seed)
    names = sorted(table)
    failures: dict[tuple, str] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a numpy warning on a bad argument is not the point here
        for _ in range(count):
            name = rng.choice(names)
            x, y = rng.choice(BAD), rng.choice([*BAD, None, None, None])
            try:
                table[name](x, y)
            except ImpactometerError:
                pass
            except Exception as exc:  # noqa: BLE001 - the unhandled failures are what is looked for
                key = (name, type(exc).__name__)
                failures.setdefault(key, f"{name}({x!r:.40}, {y!r:.40}): {type(exc).__name__}: {exc}"[:300])
    return count, list(failures.values())
