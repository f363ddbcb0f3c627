"""MATLAB recordings: v5 files through scipy.io, v7.3 (HDF5-based) files through h5py.

Read: every numeric vector variable (struct fields flattened as ``struct.field``) longer than one sample is a
channel; numeric scalars give the time base (``sample_rate``, ``fs``, ``dt`` ...) or metadata; a ``units``
struct maps channel names to unit strings; ``metadata_json`` holds metadata as JSON; other strings are kept as
metadata. A ``time`` vector gives the time base when no rate is stated.

Write (v5): one column vector per channel, ``sample_rate`` [Hz], ``start_time`` [s], ``units`` and
``metadata_json``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import scipy.io

from ..errors import RecordingError
from ..recording import Recording
from .channels import RawData, merge_metadata, metadata_from_json, metadata_to_json, plain_metadata, time_attributes

#: MATLAB char arrays in v7.3 files are stored as uint16 with this attribute
_MATLAB_CLASS = "MATLAB_class"


def _flatten(items: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in items.items():
        if key.startswith("__") or key == "#refs#":
            continue
        name = f"{prefix}{key}"
        if isinstance(value, dict) and not (key == "units" and not prefix):
            out.update(_flatten(value, name + "."))
        else:
            out[name] = value
    return out


def _v73(path: Path) -> dict[str, Any]:
    def load(node) -> Any:
        if isinstance(node, h5py.Group):
            return {key: load(node[key]) for key in node if key != "#refs#"}
        data = node[()]
        kind = node.attrs.get(_MATLAB_CLASS, b"")
        kind = kind.decode("ascii", "replace") if isinstance(kind, bytes) else str(kind)
        if kind == "char" and isinstance(data, np.ndarray) and data.dtype.kind in "iu":
            return "".join(chr(c) for c in data.reshape(-1, order="F"))
        return data
    with h5py.File(path, "r") as handle:
        return {key: load(handle[key]) for key in handle if key != "#refs#"}


def read(path: Path) -> RawData:
    """What a .mat file holds (read-only)."""
    source = str(path)
    variables = _v73(path) if h5py.is_hdf5(path) else scipy.io.loadmat(path, simplify_cells=True)
    flat = _flatten(variables)
    columns: dict[str, tuple[np.ndarray, str | None]] = {}
    scalars: dict[str, Any] = {}
    metadata: dict[str, Any] = {}
    texts: dict[str, Any] = {}
    units = flat.pop("units", {})
    if not isinstance(units, dict):
        units = {}
    for name, value in flat.items():
        if isinstance(value, str):
            if name == "metadata_json":
                metadata.update(metadata_from_json(value, source, "variable 'metadata_json'"))
            else:
                texts[name] = value
            continue
        arr = np.asarray(value)
        if arr.dtype.kind not in "iufb" or arr.size == 0:
            continue
        if arr.size == 1:
            scalars[name] = arr.reshape(-1)[0]
        elif arr.ndim == 1 or sum(s > 1 for s in arr.shape) == 1:
            unit = units.get(name.rsplit(".", 1)[-1]) if isinstance(units, dict) else None
            columns[name] = (arr.reshape(-1).astype(float), str(unit) if isinstance(unit, str) and unit else None)
    rate, start, rest = time_attributes(scalars, source)
    return RawData(columns=columns, source=source, sample_rate=rate, start_time=start,
                   metadata=merge_metadata([("variable", {k: plain_metadata(v) for k, v in rest.items()}),
                                                   ("variable", texts), ("variable 'metadata_json'", metadata)],
                                                  source))


def _variable(name: str) -> str:
    """A valid MATLAB variable name for a channel name."""
    clean = re.sub(r"\W", "_", name)
    return clean if re.match(r"[A-Za-z]", clean) else f"ch_{clean}"


def write(recording: Recording, path: Path) -> None:
    """Write ``recording`` as a MATLAB v5 file."""
    names = {name: _variable(name) for name in recording.channels}
    if len(set(names.values())) != len(names):
        raise RecordingError(f"{path}: channel names {list(names)} do not map to distinct MATLAB variables")
    content: dict[str, Any] = {names[n]: values.reshape(-1, 1) for n, values in recording.channels.items()}
    content["sample_rate"] = float(recording.sample_rate)
    content["start_time"] = float(recording.start_time)
    content["units"] = {names[n]: recording.unit(n) for n in recording.channels}
    content["metadata_json"] = metadata_to_json(recording)
    scipy.io.savemat(path, content, do_compression=True, oned_as="column")
