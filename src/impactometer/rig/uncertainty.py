"""The uncertainty of a calibrated stand's parameters: each fitted parameter's σ and their correlation, as the
``[uncertainty]`` table of its stand file stores them (a preset has none)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError

#: the table of a stand file that holds the σ and correlation of its calibrated parameters
UNCERTAINTY_KEY = "uncertainty"


@dataclass(frozen=True, kw_only=True)
class StandUncertainty:
    """σ and correlation of stand parameters fitted by a calibration.

    Attributes
    ----------
    names : tuple of str
        Dotted names of the parameters, as the fit names them (e.g. ``contact.stiffness``).
    std : tuple of float
        Standard error of each [SI], finite and >= 0.
    correlation : ndarray
        Correlation matrix (len(names), len(names)) [-], symmetric with a unit diagonal.
    """

    names: tuple[str, ...]
    std: tuple[float, ...]
    correlation: np.ndarray

    def __post_init__(self) -> None:
        names, std = tuple(self.names), tuple(float(s) for s in self.std)
        if not all(isinstance(name, str) and name for name in names) or len(set(names)) != len(names):
            raise ParameterError(f"uncertainty.names must be distinct parameter names, got {list(names)!r}")
        if len(std) != len(names) or not all(math.isfinite(s) and s >= 0.0 for s in std):
            raise ParameterError(f"uncertainty.std must hold one finite σ >= 0 [SI] per name ({len(names)}), got "
                                 f"{list(std)!r}")
        try:
            correlation = np.array(self.correlation, dtype=float)
        except (TypeError, ValueError):
            correlation = np.full(1, np.nan)
        n = len(names)
        if (correlation.shape != (n, n) or not np.all(np.isfinite(correlation))
                or not np.allclose(correlation, correlation.T, atol=1e-9)
                or not np.allclose(np.diag(correlation), 1.0, atol=1e-9) or np.any(np.abs(correlation) > 1.0 + 1e-9)):
            raise ParameterError(f"uncertainty.correlation must be a symmetric {n}x{n} matrix of numbers in [-1, 1] "
                                 f"with a unit diagonal, got {self.correlation!r}")
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "std", std)
        object.__setattr__(self, "correlation", correlation)

    def covariance(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """The covariance [SI²] of the parameters ``names`` (each one of :attr:`names`)."""
        index = [self.names.index(name) for name in names]
        std = np.array([self.std[i] for i in index])
        return self.correlation[np.ix_(index, index)] * np.outer(std, std)

    def to_table(self) -> dict[str, Any]:
        """The ``[uncertainty]`` table: ``names``, ``std`` [SI] and ``correlation`` (rows)."""
        return {"names": list(self.names), "std": list(self.std), "correlation": self.correlation.tolist()}

    @classmethod
    def from_table(cls, table: Any, *, source: str = "rig") -> StandUncertainty:
        """The uncertainty of an ``[uncertainty]`` table; ParameterError naming ``source`` for a malformed one."""
        if not isinstance(table, dict) or set(table) != {"names", "std", "correlation"}:
            raise ParameterError(f"{source}: [{UNCERTAINTY_KEY}] must be a table of names, std and correlation, got "
                                 f"{table!r}")
        try:
            return cls(names=tuple(table["names"]), std=tuple(table["std"]), correlation=table["correlation"])
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"{source}: [{UNCERTAINTY_KEY}] {exc}") from None
