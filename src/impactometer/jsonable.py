"""JSON-ready copies of values: the one cleaner of what impactometer writes as JSON (identification details,
recording metadata, study rows).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

__all__ = ["plain"]


def plain(value: Any, *, nonfinite: Literal["null", "text", "keep"] = "null", max_items: int | None = None,
          drop_none: bool = False) -> Any:
    """A copy of ``value`` made of JSON types: mappings as dicts with string keys, sequences and arrays as lists,
    numpy numbers as Python numbers, bytes decoded as UTF-8, anything else as its text.

    Parameters
    ----------
    value : Any
        Nested mappings, sequences, arrays and scalars.
    nonfinite : {"null", "text", "keep"}
        What a NaN or an infinity becomes: None, its text (``"nan"``, ``"inf"``), or itself (for writers that
        spell it themselves).
    max_items : int, optional
        An array with more elements becomes ``"<array SHAPE>"`` (None: every array is copied).
    drop_none : bool
        Leave None values out of mappings and sequences (for formats without a null, such as TOML).
    """
    def copy(item: Any) -> Any:
        if isinstance(item, Mapping):
            return {str(k): copy(v) for k, v in item.items() if not (drop_none and v is None)}
        if isinstance(item, (list, tuple)):
            return [copy(v) for v in item if not (drop_none and v is None)]
        if isinstance(item, np.ndarray):
            return copy(item.tolist()) if max_items is None or item.size <= max_items else f"<array {item.shape}>"
        if isinstance(item, np.generic):
            item = item.item()
        if isinstance(item, bytes):
            return item.decode("utf-8", "replace")
        if item is None or isinstance(item, (bool, str, int)):
            return item
        if isinstance(item, float):
            if math.isfinite(item) or nonfinite == "keep":
                return item
            return None if nonfinite == "null" else str(item)
        return str(item)

    return copy(value)
