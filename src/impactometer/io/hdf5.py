"""HDF5 recordings (h5py): one 1-D dataset per channel, the time base and metadata as attributes.

Read: the datasets of the root (or of ``group``; when the root holds none, of its only group with datasets); the
unit of a dataset from its ``unit``/``units``/``unit_string`` attribute or from its name (``Force [kN]``); the
sample rate from an attribute (``sample_rate``, ``fs``, ``dt``, ``wf_increment`` ...) of the group or the file, or a
``time`` dataset; metadata from the ``metadata`` attribute (JSON) and the other scalar attributes.

Write: the format above with ``sample_rate`` [Hz], ``start_time`` [s] and ``metadata`` (JSON) on the root.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from ..errors import RecordingError
from ..recording import Recording
from .channels import RawData, merge_metadata, metadata_from_json, metadata_to_json, time_attributes

UNIT_ATTRIBUTES = ("unit", "units", "unit_string")
FORMAT_NAME = "impactometer-recording"


def _datasets(group: h5py.Group) -> dict[str, h5py.Dataset]:
    """Numeric vector datasets (1-D, n×1 or 1×n) of ``group``; matrices and strings are not channels."""
    return {name: item for name, item in group.items()
            if isinstance(item, h5py.Dataset) and item.dtype.kind in "iuf" and item.size > 1
            and sum(s > 1 for s in item.shape) == 1}


def _samples(dataset: h5py.Dataset) -> np.ndarray:
    """A numeric dataset's samples, converted by HDF5 straight into a float64 array (no copy in the file's type)."""
    out = np.empty(dataset.shape, dtype=np.float64)
    dataset.read_direct(out)
    return out.reshape(-1)


def _unit(dataset: h5py.Dataset) -> str | None:
    for key in UNIT_ATTRIBUTES:
        if key in dataset.attrs:
            value = dataset.attrs[key]
            value = value.decode("utf-8", "replace") if isinstance(value, bytes) else value
            return str(np.asarray(value).reshape(-1)[0]) if np.asarray(value).size else None
    return None


def _node(handle: h5py.File, group: str | None, source: str) -> h5py.Group:
    groups = [name for name, item in handle.items() if isinstance(item, h5py.Group)]
    if group is not None:
        node = handle.get(group)
        if not isinstance(node, h5py.Group):
            raise RecordingError(f"{source}: group {group!r} does not exist; groups found: {groups}")
        return node
    if _datasets(handle):
        return handle
    with_data = [name for name in groups if _datasets(handle[name])]
    if len(with_data) == 1:
        return handle[with_data[0]]
    raise RecordingError(f"{source}: no channel datasets in the root; pass group (groups with datasets: "
                         f"{with_data or groups})")


def read(path: Path, *, group: str | None = None) -> RawData:
    """What an HDF5 file holds (read-only)."""
    source = str(path)
    with h5py.File(path, "r") as handle:
        node = _node(handle, group, source)
        datasets = _datasets(node)
        if not datasets:
            raise RecordingError(f"{source}: no numeric 1-D datasets in group {node.name!r}")
        columns = {name: (_samples(ds), _unit(ds)) for name, ds in datasets.items()}
        levels = [("file attribute", dict(handle.attrs))]
        if node is not handle:
            levels.append((f"group {node.name!r} attribute", dict(node.attrs)))
    rate, start, rest = time_attributes(levels, source)
    metadata = {}
    if "metadata" in rest:
        metadata = metadata_from_json(rest.pop("metadata"), source, "attribute 'metadata'")
    rest = {k: v for k, v in rest.items() if k not in ("format", "version")}
    return RawData(columns=columns, source=source, sample_rate=rate, start_time=start,
                   metadata=merge_metadata([("attribute", rest), ("attribute 'metadata'", metadata)], source))


def unwritable_name(name: str) -> str | None:
    """Why a channel called ``name`` cannot be a dataset of the file's root (None where it can): HDF5 reads a
    ``/`` as a path through groups (the channel would be a dataset in a subgroup, which reading does not look
    into) and reserves ``.``."""
    if "/" in name:
        return "HDF5 reads '/' as a path through groups, and the channel would not be read back"
    if name == ".":
        return "HDF5 reserves '.' for the group itself"
    return None


def write(recording: Recording, path: Path) -> None:
    """Write ``recording`` to a new HDF5 file."""
    with h5py.File(path, "w", track_order=True) as handle:  # channels come back in their order
        handle.attrs["format"] = FORMAT_NAME
        handle.attrs["version"] = 1
        handle.attrs["sample_rate"] = recording.sample_rate
        handle.attrs["start_time"] = recording.start_time
        handle.attrs["metadata"] = metadata_to_json(recording)
        for name, values in recording.channels.items():
            dataset = handle.create_dataset(name, data=values)
            unit = recording.unit(name)
            if unit:
                dataset.attrs["unit"] = unit
