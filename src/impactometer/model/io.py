"""Saving a :class:`SimulationResult` to HDF5 (one dataset per history, parameters as attributes)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ..outputs import API_OVERWRITE, HDF5_EXTENSIONS, check_file, write_atomically
from ..rig import to_dict
from .result import ARRAY_FIELDS, SimulationResult


def save_simulation(result: SimulationResult, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write the histories of ``result`` to an HDF5 file (``.h5``, ``.hdf5``); stand and scenario go into
    attributes. The file is written beside its target and moved into place (:func:`~impactometer.outputs.publish`):
    an existing file is replaced only with ``overwrite``, and never one that is not a regular file."""
    import h5py

    path = check_file(path, overwrite=overwrite, extensions=HDF5_EXTENSIONS, flag=API_OVERWRITE)

    def write(temporary: Path) -> None:
        with h5py.File(temporary, "w") as f:
            f.attrs["kind"] = "impactometer-simulation"
            f.attrs["sample_rate"] = result.sample_rate
            f.attrs["integrator"] = result.integrator
            for key, value in dataclasses.asdict(result.scenario).items():
                f.attrs[key] = value
            f.attrs["rig"] = json.dumps(to_dict(result.rig))
            for name in ARRAY_FIELDS:
                f.create_dataset(name, data=getattr(result, name), compression="gzip", shuffle=True)

    return write_atomically(path, write, overwrite=overwrite, flag=API_OVERWRITE)
