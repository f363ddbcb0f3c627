"""CSV recordings: a header row of channel names with units, numeric rows, optional JSON sidecar ``FILE.json``.

Read: comma, semicolon or tab separated (decimal commas are accepted when the separator is not a comma); lines
starting with ``#`` are skipped; units in brackets or parentheses (``Force [kN]``, ``Acceleration (g)``) are
converted; a ``time`` column or a sample rate (sidecar ``sample_rate`` or the ``sample_rate`` option) gives the
time base. The sidecar is a JSON object of metadata; its keys ``sample_rate`` [Hz], ``start_time`` [s] and
``channel_units`` are read as such. The rows are parsed a chunk at a time into float64 columns, so memory stays
near the size of those columns whatever the size of the file.

Write: ``time [s]`` then one column per channel with its SI unit, 17 significant digits, and the sidecar.
"""

from __future__ import annotations

import csv as _csv
import json
import re
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..recording import Recording
from ..validation import is_real
from .channels import RawData, metadata_from_json, plain_metadata

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


#: bytes of rows parsed at a time: memory stays near the float64 columns whatever the file's size
CHUNK_BYTES = 4 << 20
#: bytes looked at to choose the text encoding
ENCODING_PROBE = 1 << 16


def _encoding(path: Path) -> str:
    """The encoding the file's first bytes decode with (UTF-8, else Windows-1252, else Latin-1)."""
    with open(path, "rb") as handle:
        head = handle.read(ENCODING_PROBE)
    if b"\x00" in head:
        raise RecordingError(f"{path}: not a text file (holds NUL bytes); expected CSV text")
    head = head[:head.rfind(b"\n") + 1] or head  # whole lines only: a multi-byte character may be cut at the end
    for encoding in ("utf-8-sig", "cp1252"):
        try:
            head.decode(encoding)
        except UnicodeDecodeError:
            continue
        return encoding
    return "latin-1"


def _is_number(cell: str) -> bool:
    try:
        float(cell.replace(",", "."))
    except ValueError:
        return False
    return True


def _lines(path: Path, encoding: str):
    """Non-blank lines of the file that are not comments: the first alone, then the rest in chunks of about
    :data:`CHUNK_BYTES`."""
    with open(path, "rb") as handle:
        rest = b""
        header = True
        while True:
            block = handle.read(CHUNK_BYTES)
            if b"\x00" in block:
                raise RecordingError(f"{path}: not a text file (holds NUL bytes); expected CSV text")
            data = rest + block
            if block:  # more may follow: the last, maybe partial, line waits for the next block
                cut = data.rfind(b"\n") + 1
                data, rest = data[:cut], data[cut:]
                if not data:
                    continue  # a line longer than a block: read on
            lines = _decoded(data, encoding)
            if header and lines:
                yield [lines[0].lstrip("\ufeff")]
                lines, header = lines[1:], False
            if lines:
                yield lines
            if not block:
                return


def _decoded(data: bytes, encoding: str) -> list[str]:
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    lines = text.splitlines()
    if "#" in text or any(not line.strip() for line in lines):
        lines = [line for line in lines if line.strip() and not line.lstrip().startswith("#")]
    return lines


#: a quoted cell of a header row ("a,b", with "" for a quote inside)
_QUOTED = re.compile(r'"(?:[^"]|"")*"')


def _header(line: str, path: Path) -> tuple[list[str], str]:
    unquoted = _QUOTED.sub("", line)  # a separator inside a quoted channel name is part of the name
    separator = next((s for s in SEPARATORS if s in unquoted), ",")
    cells = next(_csv.reader([line], delimiter=separator))
    header = [cell.strip() for cell in cells]
    while header and not header[-1]:
        header.pop()
    if not header or all(_is_number(cell) for cell in header):
        raise RecordingError(f"{path}: the first row must be a header of channel names (e.g. 'time [s]', "
                             f"'Force [kN]'), got {cells[:6]}")
    if any(not cell for cell in header) or len(set(header)) != len(header):
        raise RecordingError(f"{path}: header cells must be non-empty and distinct, got {header}")
    return header, separator


def _rows(lines: list[str], first_row: int, header: list[str], separator: str, decimal_comma: bool,
          path: Path) -> np.ndarray:
    """Data rows as a (rows, columns) float array: numpy's parser, else row by row naming the bad cell."""
    text = [line.replace(",", ".") for line in lines] if decimal_comma else lines
    try:
        values = np.loadtxt(text, delimiter=separator, dtype=float, ndmin=2, quotechar='"', comments=None)
        if values.shape[1] == len(header):
            return values
    except ValueError:
        pass
    cells = []
    for i, row in enumerate(_csv.reader(lines, delimiter=separator)):
        row = [cell.strip() for cell in row]
        while len(row) > len(header) and not row[-1]:
            row.pop()
        if len(row) != len(header):
            raise RecordingError(f"{path}: data row {first_row + i} has {len(row)} cells; expected {len(header)} as "
                                 f"in the header {header}")
        for j, cell in enumerate(row):
            if not _is_number(cell):
                raise RecordingError(f"{path}: data row {first_row + i}, column {header[j]!r} holds {cell[:40]!r}; "
                                     "expected a number")
        cells.append([cell.replace(",", ".") for cell in row] if decimal_comma else row)
    return np.array(cells, dtype=float).reshape(-1, len(header))


def _table(path: Path) -> tuple[list[str], list[np.ndarray]]:
    """Header and one float64 array per column, parsed chunk by chunk into arrays sized from the file."""
    chunks = _lines(path, _encoding(path))
    first = next(chunks, None)
    if not first:
        raise RecordingError(f"{path}: file is empty; expected a header row of channel names and numeric rows")
    header, separator = _header(first[0], path)
    columns: list[np.ndarray] = []
    rows = 0
    for lines in chunks:
        # beside another separator a comma is a decimal mark: looked for in every row, since a row of whole
        # numbers ("0;0;0") has none
        decimal_comma = separator != "," and any("," in line for line in lines)
        values = _rows(lines, rows + 1, header, separator, decimal_comma, path)
        if not columns:  # size the columns from the bytes per row of the first chunk
            per_row = max(sum(len(line) + 1 for line in lines) / len(lines), 1.0)
            columns = [np.empty(int(path.stat().st_size / per_row * 1.05) + len(lines)) for _ in header]
        if rows + len(values) > columns[0].size:
            columns = [np.resize(c, int((rows + len(values)) * 1.5)) for c in columns]
        for j, column in enumerate(columns):
            column[rows:rows + len(values)] = values[:, j]
        rows += len(values)
    if not rows:
        raise RecordingError(f"{path}: no data rows below the header {header}")
    return header, [c[:rows] if c.size <= 1.1 * rows else c[:rows].copy() for c in columns]


def read(path: Path) -> RawData:
    """What a CSV file (and its sidecar) holds."""
    header, values = _table(path)
    metadata, where = _sidecar(path)
    rate = metadata.pop("sample_rate", None)
    start = metadata.pop("start_time", None)
    for field, value in (("sample_rate", rate), ("start_time", start)):
        if value is not None and not is_real(value):
            raise RecordingError(f"{where}: sidecar {field} must be a number, got {value!r}")
    columns: dict[str, tuple[np.ndarray, str | None]] = {name: (values[j], None) for j, name in enumerate(header)}
    return RawData(columns=columns, source=str(path), sample_rate=rate, start_time=start, metadata=metadata)


def unwritable_name(name: str) -> str | None:
    """Why a channel called ``name`` cannot be a cell of the header row (None where it can): the rows are read a
    line at a time, so a line break (or another control character) would cut the header."""
    if any(ord(c) < 32 or ord(c) == 127 for c in name):
        return "it holds a control character (a line break, a tab), and the header row must stay one line"
    return None


def _cell(text: str) -> str:
    """A header cell, quoted as the csv module reads it where it holds a separator or a quote."""
    return f'"{text.replace(chr(34), 2 * chr(34))}"' if any(c in text for c in (*SEPARATORS, '"')) else text


def write(recording: Recording, path: Path) -> None:
    """Write the samples of ``recording`` as CSV (``time [s]`` first, SI units; a channel name holding a
    separator or a quote is quoted)."""
    header = ["time [s]"] + [_cell(f"{name} [{recording.unit(name)}]" if recording.unit(name) else name)
                             for name in recording.channels]
    table = np.column_stack([recording.time] + list(recording.channels.values()))
    with open(path, "w", encoding="utf-8", newline="") as handle:
        handle.write(",".join(header) + "\n")
        np.savetxt(handle, table, fmt="%.17g", delimiter=",")


def write_sidecar(recording: Recording, path: Path) -> None:
    """Write the JSON sidecar (metadata, sample rate, start time) of ``recording``."""
    data = plain_metadata(recording.metadata) | {"sample_rate": recording.sample_rate,
                                                 "start_time": recording.start_time}
    path.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n", encoding="utf-8")
