"""Peak-to-peak identification of the impacting mass M1 and impact velocity V0 (paper section 4).

The package's API, re-exported here; each part lives in its own module:

- :mod:`.batch`: the solver -- :func:`identify` (a recording), :func:`identify_arrays` (force and acceleration
  arrays), :func:`solve` (a prepared segment, the two variants, early and final answers, their warnings);
- :mod:`.segment`: the first impact cut from the record and prepared (trigger, offsets, noise, pulses, edges);
- :mod:`.paper`: eqs. (3)-(5) as published; :mod:`.early`: the contact-phase fit of the first two pulses;
  :mod:`.robust`, :mod:`.gls`, :mod:`.covariance`: the contact-law agnostic least squares; :mod:`.onsets`,
  :mod:`.kinematics`, :mod:`.contact_law`: what they are built from;
- :mod:`.options`: the checks of the options and of the recording's filters;
- :mod:`.streaming`: :class:`~.streaming.StreamingIdentifier`, the dual form of :func:`identify_arrays` (import it
  from there).
"""

from __future__ import annotations

from .batch import (
    EARLY_REFUSAL,
    GRAVITY,
    LAG_FRACTION,
    MAX_RELATIVE_STD,
    NO_EARLY_DATA,
    TURNING_SCATTER_LIMIT,
    VARIANT_SOLVERS,
    answer_warnings,
    details_of,
    early_answer,
    early_refusal,
    equations,
    identify,
    identify_arrays,
    solve,
    solve_robust,
    used_samples,
)
from .options import check_unfiltered
from .paper import PAPER_NOISE_LIMIT, paper_caution, solve_paper

__all__ = ["EARLY_REFUSAL", "GRAVITY", "LAG_FRACTION", "MAX_RELATIVE_STD", "NO_EARLY_DATA", "PAPER_NOISE_LIMIT",
           "TURNING_SCATTER_LIMIT", "VARIANT_SOLVERS", "answer_warnings", "check_unfiltered", "details_of",
           "early_answer", "early_refusal", "equations", "identify", "identify_arrays", "paper_caution", "solve",
           "solve_paper", "solve_robust", "used_samples"]
