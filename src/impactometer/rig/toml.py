"""The stand's file: a TOML table of sections read with error messages that name the file, and written with an
optional ``[provenance]`` table (where a calibrated stand's numbers came from; :func:`~impactometer.rig.from_dict`
reads past it)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from ..errors import ParameterError
from ..outputs import as_path, check_file, write_atomically

#: the table of a stand file that says where its numbers came from (read past by :func:`~impactometer.rig.from_dict`)
PROVENANCE_KEY = "provenance"


def _plain(value: Any) -> Any:
    """``value`` as TOML holds it: numpy numbers as Python ones, tuples as lists, None left out of tables."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value if v is not None]
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        return value.item()
    return value


def read_table(path: str | Path) -> dict[str, Any]:
    """The table of the stand file at ``path``; ParameterError for a missing file or one that is not TOML."""
    path = as_path(path, "rig file")
    if not path.is_file():
        raise ParameterError(f"rig file {str(path)!r} does not exist")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ParameterError(f"rig file {str(path)!r} is not valid TOML: {exc}") from None
    except RecursionError:
        raise ParameterError(f"rig file {str(path)!r} nests arrays or tables too deeply; expected a stand "
                             "description (sections of numbers)") from None


def write_table(data: dict[str, Any], path: str | Path, *, overwrite: bool = False,
                provenance: dict[str, Any] | None = None) -> Path:
    """Write the stand table ``data`` to ``path``, with a ``[provenance]`` table when ``provenance`` is given (plain
    numbers, strings, lists and tables; None values are left out); refuses to overwrite unless ``overwrite``."""
    path = check_file(path, "rig file", overwrite=overwrite, flag="overwrite=True")
    if provenance is not None:
        data = {**data, PROVENANCE_KEY: _plain(provenance)}
    text = tomli_w.dumps(data)
    return write_atomically(path, lambda temporary: temporary.write_text(text, encoding="utf-8"),
                            overwrite=overwrite, flag="overwrite=True")
