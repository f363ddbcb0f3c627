"""Saving a :class:`SimulationResult` to HDF5 (one dataset per history, parameters as attributes)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from ..errors import ParameterError
from ..rig import to_dict
from .result import ARRAY_FIELDS, SimulationResult


def save_simulation(result: SimulationResult, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write the histories of ``result`` to an HDF5 file; stand and scenario go into attributes."""
    import h5py

    path = Path(path)
    if path.exists() and not overwrite:
        raise ParameterError(f"output file {str(path)!r} exists; pass overwrite=True (CLI: --force) to replace it")
    if not path.parent.is_dir():
        raise ParameterError(f"output file {str(path)!r}: folder {str(path.parent)!r} does not exist")
    with h5py.File(path, "w") as f:
        f.attrs["kind"] = "impactometer-simulation"
        f.attrs["sample_rate"] = result.sample_rate
        f.attrs["integrator"] = result.integrator
        for key, value in dataclasses.asdict(result.scenario).items():
            f.attrs[key] = value
        f.attrs["rig"] = json.dumps(to_dict(result.rig))
        for name in ARRAY_FIELDS:
            f.create_dataset(name, data=getattr(result, name), compression="gzip", shuffle=True)
    return path
