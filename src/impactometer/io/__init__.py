"""Reading and writing recordings in the formats labs use: CSV (+ JSON sidecar), HDF5, TDMS, MATLAB .mat.

The format follows the file extension (:data:`FORMATS`). Every reader failure is a :class:`RecordingError`
naming the file, the field and what was expected; reading never modifies a file; writing refuses to replace an
existing file unless ``overwrite=True`` and replaces it only once the new file is complete.
"""

from __future__ import annotations

import csv as _csv
import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import ImpactometerError, RecordingError
from ..outputs import API_OVERWRITE, as_path, check_file, publish, write_failed
from ..recording import TRUTH_KEYS, Recording, truth_value
from ..validation import check_flag
from . import csv, hdf5, mat, tdms
from .channels import RawData, assemble, merge_metadata, unreadable_name

#: file extension -> format name
FORMATS = {".csv": "csv", ".txt": "csv", ".tsv": "csv", ".h5": "hdf5", ".hdf5": "hdf5", ".hdf": "hdf5",
           ".tdms": "tdms", ".mat": "mat"}
#: format name -> reader(path, group) -> RawData
READERS: dict[str, Callable[[Path, str | None], RawData]] = {
    "csv": lambda path, group: csv.read(path), "hdf5": lambda path, group: hdf5.read(path, group=group),
    "tdms": lambda path, group: tdms.read(path, group=group), "mat": lambda path, group: mat.read(path)}
#: format name -> writer(recording, path)
WRITERS: dict[str, Callable[[Recording, Path], None]] = {
    "csv": csv.write, "hdf5": hdf5.write, "tdms": tdms.write, "mat": mat.write}
#: formats whose files have groups
GROUPED = ("hdf5", "tdms")
MANIFEST_NAME = "manifest.csv"
#: a manifest may round the truth a file states by this much (relative)
MANIFEST_TOLERANCE = 0.01


def format_of(path: str | Path) -> str:
    """Format name of ``path`` from its extension; the error lists the known extensions."""
    suffix = as_path(path, error=RecordingError).suffix.lower()
    if suffix not in FORMATS:
        raise RecordingError(f"{path}: unknown extension {suffix or '(none)'!r}; expected one of "
                             f"{', '.join(sorted(FORMATS))}")
    return FORMATS[suffix]


def read_raw(path: str | Path, *, group: str | None = None) -> RawData:
    """What the file at ``path`` holds, before channel selection (see :func:`read_recording`)."""
    path = as_path(path, error=RecordingError)
    fmt = format_of(path)
    if not path.is_file():
        raise RecordingError(f"{path}: no such file")
    if group is not None and fmt not in GROUPED:
        raise RecordingError(f"{path}: group={group!r} applies to HDF5 and TDMS files only, not {fmt}")
    try:
        return READERS[fmt](path, group)
    except ImpactometerError:
        raise
    except Exception as exc:  # any failure of the reader library on a malformed file
        detail = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise RecordingError(f"{path}: not a readable {fmt} file ({type(exc).__name__}: {detail})") from None


def read_recording(path: str | Path, *, force_channel: str | None = None, acceleration_channel: str | None = None,
                   group: str | None = None, flip_force: bool = False, flip_acceleration: bool = False,
                   acceleration_includes_gravity: bool = False, sample_rate: float | None = None,
                   time_unit: str | None = None, force_unit: str | None = None,
                   acceleration_unit: str | None = None) -> Recording:
    """Read a recording from a lab file.

    Parameters
    ----------
    path : str or Path
        ``.csv``/``.txt``/``.tsv``, ``.h5``/``.hdf5``, ``.tdms`` or ``.mat``.
    force_channel, acceleration_channel : str, optional
        Column names to use (default: a name containing ``force``/``fc``, resp. ``acc``/``a2``).
    group : str, optional
        HDF5 or TDMS group holding the channels.
    flip_force, flip_acceleration : bool
        Change the sign (force must be positive in compression, acceleration positive downward).
    acceleration_includes_gravity : bool
        The accelerometer reads specific force (a − g along the downward axis, −g at rest): g is added back.
    sample_rate : float, optional
        Sample rate [Hz] for files that state none.
    time_unit, force_unit, acceleration_unit : str, optional
        The unit the time column, the force or the acceleration is in (``"ms"``, ``"kN"``, ``"g"``), in place of
        the one the file states (an export in g under an ``[m/s^2]`` header) or assumes.

    Returns
    -------
    Recording
        ``contact_force`` [N], ``piston_acceleration`` [m/s²] when present, other columns by their name (SI when
        their unit is known); metadata from the file with ``source_channels`` naming the columns used.
    """
    for name, flag in (("flip_force", flip_force), ("flip_acceleration", flip_acceleration),
                       ("acceleration_includes_gravity", acceleration_includes_gravity)):
        check_flag(name, flag, error=RecordingError)
    raw = read_raw(path, group=group)
    try:
        return assemble(raw, force_channel=force_channel, acceleration_channel=acceleration_channel,
                        flip_force=flip_force, flip_acceleration=flip_acceleration,
                        acceleration_includes_gravity=acceleration_includes_gravity, sample_rate=sample_rate,
                        units={"time": time_unit, "contact_force": force_unit,
                               "piston_acceleration": acceleration_unit})
    except ImpactometerError:
        raise
    except Exception as exc:
        raise RecordingError(f"{path}: channels cannot be interpreted ({type(exc).__name__}: {exc})") from None


def _targets(path: Path, fmt: str) -> list[Path]:
    return [path, csv.sidecar_path(path)] if fmt == "csv" else [path]


#: format name -> why a channel name cannot be written in that format (None where it can)
NAME_CHECKS: dict[str, Callable[[str], str | None]] = {"csv": csv.unwritable_name, "hdf5": hdf5.unwritable_name}


def check_names(recording: Recording, fmt: str, path: Path) -> None:
    """RecordingError naming the first channel of ``recording`` that a ``fmt`` file would not give back under its
    name (:func:`.channels.unreadable_name`, and the format's own :data:`NAME_CHECKS`)."""
    for name in recording.channels:
        why = unreadable_name(name) or (NAME_CHECKS[fmt](name) if fmt in NAME_CHECKS else None)
        if why:
            raise RecordingError(f"{path}: channel {name!r} cannot be written to a {fmt} file and read back: {why}; "
                                 "expected a channel name that reads back as itself (rename the channel)")


def write_recording(recording: Recording, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``recording`` in the format given by the extension of ``path``; returns the path.

    A CSV file gets a JSON sidecar (``run.csv`` -> ``run.json``) with the metadata and the time base.
    """
    if not isinstance(recording, Recording):
        raise RecordingError(f"recording must be a Recording, got {type(recording).__name__}")
    path = as_path(path, error=RecordingError)
    fmt = format_of(path)
    targets = _targets(path, fmt)
    check_names(recording, fmt, path)
    flag = API_OVERWRITE
    for target in targets:
        check_file(target, overwrite=overwrite, flag=flag, error=RecordingError)
    temporary = [t.with_name(f".{t.stem}.partial-{os.getpid()}{t.suffix}") for t in targets]
    placed: list[Path] = []
    try:
        WRITERS[fmt](recording, temporary[0])
        if fmt == "csv":
            csv.write_sidecar(recording, temporary[1])
        for tmp, target in zip(temporary, targets, strict=False):
            publish(tmp, target, overwrite=overwrite, flag=flag)
            placed.append(target)
    except Exception as exc:
        for tmp in temporary:
            tmp.unlink(missing_ok=True)
        if not overwrite:  # a file placed before another writer took the name of its sidecar: this one's own
            for target in placed:
                target.unlink(missing_ok=True)
        if isinstance(exc, ImpactometerError):
            raise
        if isinstance(exc, OSError):
            raise write_failed(path, exc) from None
        raise RecordingError(f"{path}: cannot write {fmt} file ({type(exc).__name__}: {exc})") from None
    return path


def _manifest(path: Path) -> dict[str, dict[str, float]]:
    try:
        with open(path, encoding="utf-8-sig", newline="") as handle:
            rows = list(_csv.DictReader(handle))
    except (OSError, UnicodeDecodeError, _csv.Error) as exc:
        raise RecordingError(f"{path}: manifest cannot be read ({exc})") from None
    if not rows:
        raise RecordingError(f"{path}: manifest has no rows; expected columns file,mass_kg,velocity_m_s"
                             f"[,pressure_gauge_Pa]")
    columns = [c.strip() for c in rows[0] if c is not None]
    missing = [c for c in ("file", "mass_kg", "velocity_m_s") if c not in columns]
    if missing:
        raise RecordingError(f"{path}: manifest lacks column(s) {missing}; columns found: {columns}")
    out: dict[str, dict[str, float]] = {}
    for i, row in enumerate(rows, start=2):
        row = {(k or "").strip(): (v or "").strip() for k, v in row.items()}
        name = row["file"]
        if not name or name in out:
            raise RecordingError(f"{path}: line {i}: file must be a distinct non-empty name, got {name!r}")
        out[name] = {key: truth_value(key, row[key], f"{path}: line {i}: ") for key in TRUTH_KEYS
                     if row.get(key, "") != ""}
    return out


def read_calibration_set(folder: str | Path, manifest: str | Path | None = None,
                         **read_options: Any) -> list[Recording]:
    """All recordings in ``folder`` (sorted by name), the manifest's truth completing each file's metadata.

    The manifest (default ``folder/manifest.csv`` when present) has columns ``file,mass_kg,velocity_m_s`` and
    optionally ``pressure_gauge_Pa``; ``read_options`` go to :func:`read_recording`. Where a file states a truth
    too, the two must agree within :data:`MANIFEST_TOLERANCE` (a manifest with swapped columns is refused).
    """
    folder = as_path(folder, "folder", error=RecordingError)
    if not folder.is_dir():
        raise RecordingError(f"{folder}: not a folder; expected a folder of recordings")
    manifest_path = as_path(manifest, "manifest", error=RecordingError) if manifest is not None \
        else folder / MANIFEST_NAME
    if manifest is not None and not manifest_path.is_file():
        raise RecordingError(f"{manifest_path}: manifest does not exist")
    truth = _manifest(manifest_path) if manifest_path.is_file() else {}
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in FORMATS
                   and not p.name.startswith(".") and p.resolve() != manifest_path.resolve())
    if not files:
        raise RecordingError(f"{folder}: no recordings (files ending in {', '.join(sorted(FORMATS))})")
    unknown = sorted(set(truth) - {p.name for p in files})
    if unknown:
        raise RecordingError(f"{manifest_path}: file(s) {unknown} not found in {folder}")
    recordings = []
    for path in files:
        recording = read_recording(path, **read_options)
        if path.name in truth:  # the manifest completes the file's metadata; where both state a truth, they agree
            metadata = merge_metadata([("the file's", recording.metadata), ("the manifest's", truth[path.name])],
                                      str(path), tolerance=MANIFEST_TOLERANCE)
            recording = dataclasses.replace(recording, metadata=metadata)
        recordings.append(recording)
    return recordings


__all__ = ["FORMATS", "READERS", "WRITERS", "format_of", "read_raw", "read_recording", "write_recording",
           "read_calibration_set"]
