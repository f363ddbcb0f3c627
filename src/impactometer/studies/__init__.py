"""The paper's numerical studies (Figs. 3-9 and the absorber), runnable locally or on a Dask cluster.

Each study is registered in :data:`STUDIES` (:mod:`.base`); ``get_study(name).run(options)`` returns its tidy
table in this process, :func:`run_study` / :func:`run_studies` run it in parallel with persisted, resumable chunks
and write the CSV tables, the figures and the ``index.html`` report.

Imports point one way: :mod:`.base` (what a study is, the registry) <- the study modules and :mod:`.runner`
(<- :mod:`.report`); this package only re-exports.
"""

from __future__ import annotations

from .base import MODULES, PAPER_RANGES, STUDIES, Study, StudyOptions, get_study, load_studies, register
from .runner import StudyRun, available_studies, run_studies, run_study

__all__ = ["MODULES", "PAPER_RANGES", "STUDIES", "Study", "StudyOptions", "StudyRun", "available_studies",
           "get_study", "load_studies", "register", "run_studies", "run_study"]
