"""Tidy tables: grouping statistics, CSV writing (csv module), number formatting for the report."""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from .validation import is_finite

Row = dict[str, Any]


def columns(rows: Sequence[Row]) -> list[str]:
    """Column names in first-seen order over all rows."""
    seen: dict[str, None] = {}
    for row in rows:
        for key in row:
            seen.setdefault(key, None)
    return list(seen)


def to_csv(rows: Sequence[Row]) -> str:
    """CSV text of ``rows`` (header = every column; missing cells empty; floats in full precision)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns(rows), lineterminator="\n", restval="")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (repr(float(v)) if isinstance(v, (float, np.floating)) else v) for k, v in row.items()})
    return buffer.getvalue()


def read_csv(text: str) -> list[Row]:
    """Rows of a CSV written by :func:`to_csv` (numbers parsed back to int/float)."""
    def parse(value: str) -> Any:
        for kind in (int, float):
            try:
                return kind(value)
            except ValueError:
                pass
        return value

    return [{k: parse(v) for k, v in row.items()} for row in csv.DictReader(io.StringIO(text))]


def group_stats(rows: Iterable[Row], by: Sequence[str], values: Sequence[str], *,
                scale: float = 100.0) -> list[Row]:
    """Mean and max of |value| per group of ``by`` columns, failures (NaN) counted apart.

    Returns rows with the ``by`` columns, ``n``, ``failed`` and ``mean_abs_<value>``, ``max_abs_<value>``
    (multiplied by ``scale``; 100 turns fractions into percent).
    """
    groups: dict[tuple, list[Row]] = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in by), []).append(row)
    out = []
    for key, members in groups.items():
        entry: Row = dict(zip(by, key, strict=False))
        entry["n"] = len(members)
        failed = [r for r in members if any(not is_finite(r.get(v)) for v in values)]
        entry["failed"] = len(failed)
        for v in values:
            data = np.array([abs(float(r[v])) for r in members if is_finite(r.get(v))])
            entry[f"mean_abs_{v}"] = float(np.mean(data)) * scale if data.size else math.nan
            entry[f"max_abs_{v}"] = float(np.max(data)) * scale if data.size else math.nan
        out.append(entry)
    return out


def percent_labels(rows: Iterable[Row]) -> list[Row]:
    """Rows of :func:`group_stats` with readable headers: ``mean_abs_x`` -> ``mean |x| [%]``."""
    def label(key: str) -> str:
        for stat in ("mean", "max"):
            if key.startswith(f"{stat}_abs_"):
                return f"{stat} |{key[len(stat) + 5:].replace('_', ' ')}| [%]"
        return key
    return [{label(k): v for k, v in row.items()} for row in rows]


def fmt(value: Any) -> str:
    """A cell for humans: 4 significant digits for floats, ``failed`` for NaN."""
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if not math.isfinite(value):
            return "–"
        if value == round(value) and abs(value) < 1e9:
            return str(int(value))  # grid values such as 20000 Pa or 50000 Hz
        return f"{value:.4g}"
    return str(value)


def pick(rows: Iterable[Row], **equal: Any) -> list[Row]:
    """Rows whose columns equal the given values."""
    return [r for r in rows if all(r.get(k) == v for k, v in equal.items())]


def finite_values(rows: Iterable[Row], column: str) -> np.ndarray:
    """Finite values of ``column`` as an array."""
    return np.array([float(r[column]) for r in rows if is_finite(r.get(column))])


def flag(value: Any) -> bool:
    """A flag of a row, also as read back from a CSV table (``"True"``)."""
    return value is True or value == "True"


def number(value: Any) -> float:
    """A number of a row, NaN for an empty cell (None, or ``""`` as read back from a CSV table)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan
