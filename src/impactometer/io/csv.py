"""CSV recordings: a header row of channel names with units, numeric rows, optional JSON sidecar ``FILE.json``.

Read: comma, semicolon or tab separated (decimal commas are accepted when the separator is not a comma); lines
starting with ``#`` are skipped; units in brackets or parentheses (``Force [kN]``, ``Acceleration (g)``) are
converted; a ``time`` column or a sample rate (sidecar ``sample_rate`` or the ``sample_rate`` option) gives the
time base. The sidecar is a JSON object of metadata; its keys ``sample_rate`` [Hz], ``start_time`` [s] and
``channel_units`` are read as such.

Write: ``time [s]`` then one column per channel with its SI unit, 17 significant digits, and the sidecar.
"""

from __future__ import annotations

import csv as _csv
import json
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..recording import Recording
from .channels import RawData, metadata_from_json, plain

SEPARATORS = (";", "\t", ",")


def sidecar_path(path: Path) -> Path:
    """``run.csv`` -> ``run.json``."""
    return Path(path).with_suffix(".json")


def _sidecar(path: Path) -> tuple[dict, Path | None]:
    for candidate in (sidecar_path(path), Path(str(path) + ".json")):
        if candidate.is_file():
            try:
                text = candidate.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError) as exc:
                raise RecordingError(f"{candidate}: sidecar cannot be read ({exc})") from None
            return metadata_from_json(text, str(candidate), "sidecar"), candidate
    return {}, None


def _text(path: Path) -> str:
    data = path.read_bytes()
    if b"\x00" in data:
        raise RecordingError(f"{path}: not a text file (holds NUL bytes); expected CSV text")
    for encoding in ("utf-8-sig", "cp1252"):
        try:
            return data.decode(encoding)
        except UnicodeDecodeError:
            continue
    return data.decode("latin-1")


def _is_number(cell: str) -> bool:
    try:
        float(cell.replace(",", "."))
    except ValueError:
        return False
    return True


def _table(path: Path) -> tuple[list[str], np.ndarray]:
    lines = [line for line in _text(path).splitlines() if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise RecordingError(f"{path}: file is empty; expected a header row of channel names and numeric rows")
    separator = next((s for s in SEPARATORS if s in lines[0]), ",")
    rows = list(_csv.reader(lines, delimiter=separator))
    header = [cell.strip() for cell in rows[0]]
    while header and not header[-1]:
        header.pop()
    if not header or all(_is_number(cell) for cell in header):
        raise RecordingError(f"{path}: the first row must be a header of channel names (e.g. 'time [s]', "
                             f"'Force [kN]'), got {rows[0][:6]}")
    if any(not cell for cell in header) or len(set(header)) != len(header):
        raise RecordingError(f"{path}: header cells must be non-empty and distinct, got {header}")
    body = rows[1:]
    if not body:
        raise RecordingError(f"{path}: no data rows below the header {header}")
    decimal_comma = separator != "," and any("," in cell for cell in body[0])
    cells = []
    for i, row in enumerate(body):
        row = [cell.strip() for cell in row]
        while len(row) > len(header) and not row[-1]:
            row.pop()
        if len(row) != len(header):
            raise RecordingError(f"{path}: data row {i + 1} has {len(row)} cells; expected {len(header)} as in "
                                 f"the header {header}")
        cells.append([cell.replace(",", ".") for cell in row] if decimal_comma else row)
    try:
        values = np.array(cells, dtype=float)
    except ValueError:
        for i, row in enumerate(cells):
            for j, cell in enumerate(row):
                if not _is_number(cell):
                    raise RecordingError(f"{path}: data row {i + 1}, column {header[j]!r} holds {cell!r}; "
                                         f"expected a number") from None
        raise RecordingError(f"{path}: data rows must hold numbers") from None
    return header, values


def read(path: Path) -> RawData:
    """What a CSV file (and its sidecar) holds."""
    header, values = _table(path)
    metadata, where = _sidecar(path)
    rate = metadata.pop("sample_rate", None)
    start = metadata.pop("start_time", None)
    for field, value in (("sample_rate", rate), ("start_time", start)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
            raise RecordingError(f"{where}: sidecar {field} must be a number, got {value!r}")
    columns: dict[str, tuple[np.ndarray, str | None]] = {name: (values[:, j], None) for j, name in enumerate(header)}
    return RawData(columns=columns, source=str(path), sample_rate=rate, start_time=start, metadata=metadata)


def write(recording: Recording, path: Path) -> None:
    """Write the samples of ``recording`` as CSV (``time [s]`` first, SI units)."""
    header = ["time [s]"] + [f"{name} [{recording.unit(name)}]" if recording.unit(name)
                             else name for name in recording.channels]
    table = np.column_stack([recording.time] + list(recording.channels.values()))
    with open(path, "w", encoding="utf-8", newline="") as handle:
        handle.write(",".join(header) + "\n")
        np.savetxt(handle, table, fmt="%.17g", delimiter=",")


def write_sidecar(recording: Recording, path: Path) -> None:
    """Write the JSON sidecar (metadata, sample rate, start time) of ``recording``."""
    data = plain(recording.metadata) | {"sample_rate": recording.sample_rate, "start_time": recording.start_time}
    path.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n", encoding="utf-8")
