"""Response maps in HDF5 (h5py): schema version, axes, features, feature-set parameters, stand, provenance.

Layout (schema 1): root attributes ``schema`` = ``"impactometer-response-map"``, ``schema_version``,
``feature_set``, ``feature_labels`` (JSON), ``feature_params`` (JSON), ``sample_rate`` [Hz], ``rig`` (JSON of
``rig.to_dict``), ``provenance`` (JSON), ``content_sha256`` (the SHA-256 of all the others and the datasets,
checked on loading when present); datasets ``masses`` [kg], ``velocities`` [m/s], ``pressures_gauge`` [Pa] and
``values`` (features, pressures, masses, velocities). No pickle: only numbers and JSON text.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from ...errors import ImpactometerError, ParameterError, ResponseMapError
from ...outputs import API_OVERWRITE, as_path, check_file, write_atomically
from ...recording import check_sample_rate
from .database import SCHEMA_VERSION, ResponseMap
from .features import get_feature_set

SCHEMA = "impactometer-response-map"
_ATTRS = ("schema", "schema_version", "feature_set", "feature_labels", "feature_params", "sample_rate", "rig",
          "provenance")
_DATASETS = ("masses", "velocities", "pressures_gauge", "values")
#: attribute holding the SHA-256 of the other attributes and the datasets (a byte changed anywhere is noticed)
CHECKSUM = "content_sha256"


def _digest(attrs, arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 of a map file's attributes (:data:`_ATTRS`, as read back) and datasets (as float64)."""
    sha = hashlib.sha256()
    for key in _ATTRS:
        sha.update(f"{key}={_text(attrs[key])};".encode())
    for name in _DATASETS:
        data = np.ascontiguousarray(arrays[name], dtype=np.float64)
        sha.update(f"{name}{data.shape};".encode())
        sha.update(data.tobytes())
    return sha.hexdigest()


def save_map(rmap: ResponseMap, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write ``rmap`` to an HDF5 file; refuses to overwrite an existing file unless ``overwrite``.

    The file is written next to its target and renamed into place, so a failure never leaves a half-written map.
    """
    import h5py

    if not isinstance(rmap, ResponseMap):
        raise ParameterError(f"rmap must be a ResponseMap, got {type(rmap).__name__}")
    path = check_file(path, overwrite=overwrite, flag=API_OVERWRITE)

    def write(temporary: Path) -> None:
        with h5py.File(temporary, "w") as h5:
            h5.attrs["schema"] = SCHEMA
            h5.attrs["schema_version"] = SCHEMA_VERSION
            h5.attrs["feature_set"] = rmap.feature_set
            h5.attrs["feature_labels"] = json.dumps(list(rmap.labels))
            h5.attrs["feature_params"] = json.dumps(rmap.feature_params)
            h5.attrs["sample_rate"] = float(rmap.sample_rate)
            h5.attrs["rig"] = json.dumps(rmap.rig)
            h5.attrs["provenance"] = json.dumps(rmap.provenance)
            for name in _DATASETS:
                h5.create_dataset(name, data=getattr(rmap, name))
            h5.attrs[CHECKSUM] = _digest(h5.attrs, {name: np.asarray(h5[name][()], dtype=float) for name in _DATASETS})

    return write_atomically(path, write, overwrite=overwrite, flag=API_OVERWRITE)


def _json(attrs, key: str, where: str):
    try:
        return json.loads(_text(attrs[key]))
    except (TypeError, ValueError, RecursionError):
        raise ResponseMapError(f"{where}: attribute {key!r} is not valid JSON; expected a map written by "
                               "impactometer map build") from None


def _text(value) -> str:
    """An attribute that must hold text, as text (bytes decoded); anything else as its one-line repr."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, str):
        return value
    if isinstance(value, np.ndarray | np.generic):
        value = value.tolist()
    return " ".join(repr(value).split())


def _number(attrs, key: str, where: str) -> float:
    """A numeric scalar attribute; ResponseMapError naming it otherwise."""
    value = attrs[key]
    arr = np.asarray(value) if not isinstance(value, (str, bytes)) else np.asarray([])
    if arr.size != 1 or arr.dtype.kind not in "iuf" or not np.isfinite(arr.reshape(-1)[0]):
        shown = _text(value)
        raise ResponseMapError(f"{where}: attribute {key!r} must be a finite number, got "
                               f"{shown if len(shown) <= 40 else shown[:37] + '...'}; the file was edited or damaged")
    return float(arr.reshape(-1)[0])


def load_map(path: str | Path) -> ResponseMap:
    """Read and validate a response map written by :func:`save_map`.

    Raises ResponseMapError for a missing, non-HDF5, corrupt, edited, foreign or older-schema file.
    """
    import h5py

    path = as_path(path, error=ResponseMapError)
    where = str(path)
    if not path.is_file():
        raise ResponseMapError(f"{where}: no such map file; expected an HDF5 file from impactometer map build")
    try:
        h5 = h5py.File(path, "r")
    except Exception:  # h5py raises OSError, and other errors on damaged files
        raise ResponseMapError(f"{where}: not an HDF5 file (or corrupt); expected a map from impactometer map "
                               "build") from None
    try:
        with h5:
            fields = _read(h5, where)
    except ImpactometerError:
        raise
    except Exception as exc:  # a damaged file fails anywhere inside h5py
        detail = " ".join(str(exc).split())[:120]
        raise ResponseMapError(f"{where}: the file is damaged ({type(exc).__name__}: {detail}); rebuild it with "
                               "impactometer map build") from None
    feature_set, labels, intact = fields.pop("feature_set"), fields.pop("labels"), fields.pop("intact")
    try:
        expected = list(get_feature_set(feature_set).labels)
        if labels != expected:
            raise ResponseMapError(f"feature labels {labels} do not match feature set {feature_set!r} {expected}")
        for key in ("feature_params", "rig", "provenance"):
            if not isinstance(fields[key], dict):
                raise ResponseMapError("feature_params, rig and provenance must be JSON objects")
        rmap = ResponseMap(feature_set=feature_set, **fields)
    except ImpactometerError as exc:
        raise ResponseMapError(f"{where}: {exc}") from None
    if not intact:  # valid in every part, yet not what map build wrote
        raise ResponseMapError(f"{where}: the content does not match its checksum; the file was damaged or edited "
                               "after map build (rebuild it with impactometer map build)")
    return rmap


def _read(h5, where: str) -> dict:
    """Attributes and datasets of an open map file, checked for type."""
    import h5py

    missing = [k for k in _ATTRS if k not in h5.attrs] + [k for k in _DATASETS if k not in h5]
    if "schema" in h5.attrs and _text(h5.attrs["schema"]) != SCHEMA:
        raise ResponseMapError(f"{where}: schema {_text(h5.attrs['schema'])[:40]!r} is not {SCHEMA!r}; expected a "
                               "response map")
    if "schema_version" in h5.attrs:
        version = _number(h5.attrs, "schema_version", where)
        if version != SCHEMA_VERSION:
            raise ResponseMapError(f"{where}: schema version {version:g}, this impactometer reads version "
                                   f"{SCHEMA_VERSION}; rebuild the map with impactometer map build")
    if missing:
        raise ResponseMapError(f"{where}: missing {missing}; expected attributes {list(_ATTRS)} and datasets "
                               f"{list(_DATASETS)} (schema {SCHEMA_VERSION})")
    arrays = {}
    for key in _DATASETS:
        item = h5[key]
        if not isinstance(item, h5py.Dataset) or item.dtype.kind not in "iuf":
            raise ResponseMapError(f"{where}: {key!r} must be a numeric dataset; the file was edited or damaged")
        arrays[key] = np.asarray(item[()], dtype=float)
    intact = CHECKSUM not in h5.attrs or _text(h5.attrs[CHECKSUM]) == _digest(h5.attrs, arrays)
    return {"intact": intact, "feature_set": _text(h5.attrs["feature_set"]),
            "labels": _json(h5.attrs, "feature_labels", where),
            "feature_params": _json(h5.attrs, "feature_params", where), "rig": _json(h5.attrs, "rig", where),
            "provenance": _json(h5.attrs, "provenance", where),
            "sample_rate": check_sample_rate(_number(h5.attrs, "sample_rate", where), f"{where}: attribute "
                                             "'sample_rate'", error=ResponseMapError), **arrays}

