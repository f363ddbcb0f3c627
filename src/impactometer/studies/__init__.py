"""The paper's numerical studies (Figs. 3-9 and the absorber), runnable locally or on a Dask cluster.

Each study is registered in :data:`STUDIES`; ``get_study(name).run(options)`` returns its tidy table in this
process, :func:`run_study` / :func:`run_studies` run it in parallel with persisted, resumable chunks and write the
CSV tables, the figures and the ``index.html`` report.
"""

from __future__ import annotations

import importlib

from .base import PAPER_RANGES, STUDIES, Study, StudyOptions, get_study, register
from .runner import StudyRun, available_studies, run_studies, run_study

#: study modules, in report order
MODULES = ("cases", "parameters", "noise", "sampling", "response_map", "absorption", "valve_design", "peak_force")

__all__ = ["PAPER_RANGES", "STUDIES", "Study", "StudyOptions", "StudyRun", "available_studies", "get_study",
           "load_studies", "register", "run_studies", "run_study"]


def load_studies() -> dict[str, Study]:
    """Import every study module (each registers itself) and return the registry."""
    for module in MODULES:
        try:
            importlib.import_module(f"{__name__}.{module}")
        except ModuleNotFoundError as exc:
            if not exc.name or not exc.name.startswith(f"{__name__}.{module}"):
                raise
    return STUDIES
