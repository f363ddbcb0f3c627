"""The registry of studies: :data:`STUDIES`, :func:`register`, :func:`get_study` and :func:`load_studies`.

The study modules register themselves when imported; :func:`load_studies` imports every one of them (by name,
so that a tree without a study's dependencies still lists the others). This module imports no other module of
the package's studies, so every other one may import it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from ..errors import ParameterError, shown

if TYPE_CHECKING:
    from .base import Study

#: study modules, in report order
MODULES = ("cases", "parameters", "noise", "sampling", "response_map", "absorption", "valve_design", "absorber_design",
           "peak_force")

#: study name -> Study (filled by the study modules)
STUDIES: dict[str, Study] = {}


def register(study: Study) -> Study:
    """Add ``study`` to :data:`STUDIES` and return it."""
    STUDIES[study.name] = study
    return study


def get_study(name: str) -> Study:
    """The registered study ``name``; an unknown name raises with the list of valid names."""
    if not isinstance(name, str) or name not in STUDIES:
        raise ParameterError(f"study must be one of {sorted(STUDIES)} or 'all', got {shown(name)}")
    return STUDIES[name]


def load_studies() -> dict[str, Study]:
    """Import every study module (each registers itself) and return the registry.

    A study module that cannot be imported because it is absent from this tree is skipped; any other import
    error propagates.
    """
    package = __name__.rpartition(".")[0]
    for module in MODULES:
        try:
            importlib.import_module(f"{package}.{module}")
        except ModuleNotFoundError as exc:
            if not exc.name or not exc.name.startswith(f"{package}.{module}"):
                raise
    return STUDIES
