"""The paper's numerical studies (Figs. 3-9 and the absorber), runnable locally or on a Dask cluster.

Each study is registered in :data:`STUDIES` (:mod:`.registry`); ``get_study(name).run(options)`` returns its tidy
table in this process, :func:`run_study` / :func:`run_studies` run it in parallel with persisted, resumable chunks
and write the CSV tables, the figures and the ``index.html`` report.

Imports point one way: :mod:`.registry` <- :mod:`.base` <- the study modules and :mod:`.runner`
(<- :mod:`.report`); this package only re-exports.
"""

from __future__ import annotations

from .base import PAPER_RANGES, Study, StudyOptions
from .registry import MODULES, STUDIES, get_study, load_studies, register
from .runner import StudyRun, available_studies, run_studies, run_study

__all__ = ["MODULES", "PAPER_RANGES", "STUDIES", "Study", "StudyOptions", "StudyRun", "available_studies",
           "get_study", "load_studies", "register", "run_studies", "run_study"]
