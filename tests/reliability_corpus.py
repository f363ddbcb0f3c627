"""How a run of the reliability corpus is judged, and the writers of damaged files (the cases:
:mod:`reliability_cases`).

Shared by ``tests/test_reliability.py`` (every case, in-process) and ``scripts/reliability_fuzz.py`` (the same cases
and heavier ones, with the acceptance table). A case is a command line with what it may do:

- ``refuse``: exit 2 with one line -- or answer with a warning;
- ``answer``: exit 0; an identified mass and velocity within tolerance of the truth (and, where the case says so,
  within a number of their standard errors), or carrying a warning;
- ``either``: one of the two.

A run is judged ``handled``, ``unhandled`` (a traceback, another exit status, an error of several lines or with a
numpy repr, an error line on standard output instead of standard error, a refusal that does not name the cause
the case states), ``silent-wrong`` (exit 0 with a wrong
answer and no warning, or where a refusal was due), ``data-loss`` (a protected file changed, a half-written file
left) or ``over-refused`` (a valid input refused).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import math
import re
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

from impactometer.cli import main

#: an answer within this relative error of the truth is right (mass, velocity)
TOLERANCE = (0.10, 0.05)
VERDICTS = ("handled", "unhandled", "silent-wrong", "data-loss", "over-refused")
FS = 50e3


@dataclass
class Case:
    category: str
    name: str
    argv: list[str]
    expect: str = "refuse"
    truth: tuple[float, float] | None = None
    protect: tuple[Path, ...] = ()
    same_as: str | None = None  # a case whose outcome this one must share (stream and identify)
    slow: bool = False
    sigmas: float | None = None  # an answer must also lie within this many standard errors of the truth
    reason: str | None = None  # a refusal must name this cause


@dataclass
class Outcome:
    code: int | None
    output: str  # standard output, then standard error (where the error line goes)
    crash: str = ""
    changed: list[str] = field(default_factory=list)
    stdout: str | None = None  # standard output alone, where it was captured apart from standard error


def _sha(path: Path) -> str | None:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


def run(case: Case) -> Outcome:
    """Run a case's command line in this process, capturing its output and exit status."""
    before = {p: _sha(p) for p in case.protect}
    out, err = io.StringIO(), io.StringIO()
    code, crash = 0, ""
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main(case.argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:  # noqa: BLE001 - anything that escapes the command line is what we look for
            code, crash = None, traceback.format_exc()
    changed = [str(p) for p in case.protect if _sha(p) != before[p]]
    for p in case.protect:  # a half-written file left next to a target
        changed += [str(q) for q in p.parent.glob(f".{p.stem}*") if ".partial-" in q.name or q.suffix == ".tmp"]
    return Outcome(code=code, output=out.getvalue() + err.getvalue(), crash=crash, changed=changed,
                   stdout=out.getvalue())


def answer(outcome: Outcome) -> tuple[float, float, list[str]] | None:
    """(mass, velocity, warnings) of the last identification a --json run printed, or None."""
    found = None
    for line in outcome.output.splitlines():
        with contextlib.suppress(ValueError):
            data = json.loads(line)
            if isinstance(data, dict) and "mass_kg" in data and "velocity_m_s" in data:
                found = (data["mass_kg"], data["velocity_m_s"], data.get("warnings") or [])
    return found


def spread(outcome: Outcome) -> tuple[float | None, float | None]:
    """(mass, velocity) standard errors of the last identification a --json run printed, or Nones."""
    found: tuple[float | None, float | None] = (None, None)
    for line in outcome.output.splitlines():
        with contextlib.suppress(ValueError):
            data = json.loads(line)
            if isinstance(data, dict) and "mass_kg" in data:
                found = (data.get("mass_std_kg"), data.get("velocity_std_m_s"))
    return found


_NUMPY_REPR = re.compile(r"\bnp\.\w+\(|array\(")


def judge(case: Case, outcome: Outcome, peer: Outcome | None = None) -> tuple[str, str]:
    """(verdict, reason) of one run (``peer``: the run of ``case.same_as``)."""
    text = outcome.output
    if outcome.changed:
        return "data-loss", f"changed or left behind: {outcome.changed}"
    if outcome.crash or outcome.code not in (0, 2) or "Traceback" in text or "Exception ignored" in text:
        return "unhandled", (outcome.crash.strip().splitlines() or [f"exit {outcome.code}"])[-1][:200]
    if outcome.stdout is not None and any(line.startswith("error:") for line in outcome.stdout.splitlines()):
        return "unhandled", "an error line on standard output (errors go to standard error)"
    if outcome.code == 2:
        errors = [line for line in text.splitlines() if line.startswith("error:")]
        if len(errors) != 1 or _NUMPY_REPR.search(errors[0]):
            return "unhandled", f"error output: {errors[:3]}"
        if case.expect == "answer":
            return "over-refused", errors[0][:200]
        if case.reason and case.reason not in errors[0]:
            return "unhandled", f"refused without naming {case.reason!r}: {errors[0][:160]}"
        return "handled", errors[0][:200]
    found = answer(outcome)
    if peer is not None and peer.code == 2 and found is not None and not found[2]:
        return "silent-wrong", "answered without a warning where the batch identification refuses"
    if peer is not None and found is not None and (other := answer(peer)) is not None \
            and not math.isclose(found[0], other[0], rel_tol=1e-9):
        return "silent-wrong", f"M1 = {found[0]:.6g} kg, the batch identification {other[0]:.6g} kg"
    if found is not None and case.truth is not None:
        mass, velocity, warnings = found
        right = (mass is not None and velocity is not None and abs(mass / case.truth[0] - 1) <= TOLERANCE[0]
                 and abs(velocity / case.truth[1] - 1) <= TOLERANCE[1])
        stds = spread(outcome)
        if right and not warnings and case.sigmas is not None and None not in stds:
            z = max(abs(mass - case.truth[0]) / stds[0], abs(velocity - case.truth[1]) / stds[1])
            if z > case.sigmas:
                return "silent-wrong", (f"M1 = {mass:.4g} ± {stds[0]:.2g} kg, V0 = {velocity:.4g} ± {stds[1]:.2g} m/s "
                                        f"for {case.truth}: {z:.1f} standard errors off, no warning")
        if right or warnings:
            return "handled", f"M1 = {mass:.4g} kg, V0 = {velocity:.4g} m/s, {len(warnings)} warning(s)"
        return "silent-wrong", f"M1 = {mass:.4g} kg, V0 = {velocity:.4g} m/s for {case.truth}, no warning"
    if case.expect == "refuse" and "warning" not in text:
        return "silent-wrong", "exit 0 where a refusal was due"
    return "handled", "exit 0"


# ---------------------------------------------------------------------------------------------------------- files
def write_h5(path: Path, channels: dict, attrs: dict | None = None, *, group: str | None = None,
             group_attrs: dict | None = None) -> Path:
    with h5py.File(path, "w") as h5:
        for key, value in (attrs or {}).items():
            h5.attrs[key] = value
        node = h5.create_group(group) if group else h5
        for key, value in (group_attrs or {}).items():
            node.attrs[key] = value
        for name, values in channels.items():
            node.create_dataset(name, data=values)
    return path


def write_tdms(path: Path, channels: dict, *, channel_props: dict | None = None, group_props: dict | None = None,
               root_props: dict | None = None) -> Path:
    objects = [RootObject(properties=root_props or {}), GroupObject("g", properties=group_props or {})]
    objects += [ChannelObject("g", name, np.asarray(values, dtype=float), properties=dict(channel_props or {}))
                for name, values in channels.items()]
    with TdmsWriter(str(path)) as writer:
        writer.write_segment(objects)
    return path


def write_csv(path: Path, columns: dict, *, sidecar=None, fmt: str = "%.9g", separator: str = ",") -> Path:
    table = np.column_stack(list(columns.values()))
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(separator.join(columns) + "\n")
        np.savetxt(handle, table, fmt=fmt, delimiter=separator)
    if sidecar is not None:
        path.with_suffix(".json").write_text(sidecar if isinstance(sidecar, str) else json.dumps(sidecar))
    return path
