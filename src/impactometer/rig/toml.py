"""The stand's file: a TOML table of sections read with error messages that name the file, and written with an
optional ``[provenance]`` table (where a calibrated stand's numbers came from) and ``[uncertainty]`` table (the σ
and correlation of its calibrated parameters, :mod:`.uncertainty`); :func:`~impactometer.rig.from_dict` reads past
both."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from ..errors import ParameterError
from ..jsonable import plain
from ..outputs import as_path, check_file, write_atomically
from .uncertainty import UNCERTAINTY_KEY

#: the table of a stand file that says where its numbers came from (read past by :func:`~impactometer.rig.from_dict`)
PROVENANCE_KEY = "provenance"


def read_table(path: str | Path) -> dict[str, Any]:
    """The table of the stand file at ``path``; ParameterError for a missing file or one that is not TOML."""
    path = as_path(path, "rig file")
    if not path.is_file():
        raise ParameterError(f"rig file {str(path)!r} does not exist")
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ParameterError(f"rig file {str(path)!r} is not valid TOML: {exc}") from None
    except RecursionError:
        raise ParameterError(f"rig file {str(path)!r} nests arrays or tables too deeply; expected a stand "
                             "description (sections of numbers)") from None
    if not set(table) - {PROVENANCE_KEY, UNCERTAINTY_KEY}:
        raise ParameterError(f"rig file {str(path)!r} holds no stand; expected a stand description (a name, "
                             "sections such as [contact], [cylinder], [gas], [friction]); an empty file is not taken "
                             "for the built-in stand")
    return table


def loading(path: Path, error: ParameterError) -> ParameterError:
    """``error``, raised while building the stand of the file at ``path``, as an error about that file: its message
    names the file and the file's field, and its ``field`` is ``rig`` (the option that named the file), not the
    stand parameter the file got wrong."""
    message = str(error)
    about = message if message.startswith(f"{path}: ") else f"{path}: {message}"
    return ParameterError(about, field="rig", expected=about.removeprefix(f"{path}: "))


def table_text(data: dict[str, Any], provenance: dict[str, Any] | None = None,
               uncertainty: dict[str, Any] | None = None) -> str:
    """The stand table ``data`` as TOML text, with a ``[provenance]`` table when ``provenance`` is given (plain
    numbers, strings, lists and tables; None values are left out) and an ``[uncertainty]`` table when
    ``uncertainty`` is given (:meth:`.uncertainty.StandUncertainty.to_table`)."""
    if uncertainty is not None:
        data = {**data, UNCERTAINTY_KEY: uncertainty}
    if provenance is not None:
        data = {**data, PROVENANCE_KEY: plain(provenance, nonfinite="keep", drop_none=True)}
    return tomli_w.dumps(data)


def write_table(data: dict[str, Any], path: str | Path, *, overwrite: bool = False,
                provenance: dict[str, Any] | None = None, uncertainty: dict[str, Any] | None = None) -> Path:
    """Write the stand table ``data`` to ``path`` (:func:`table_text`); refuses to overwrite unless
    ``overwrite``."""
    path = check_file(path, "rig file", overwrite=overwrite, flag="overwrite=True")
    text = table_text(data, provenance, uncertainty)
    return write_atomically(path, lambda temporary: temporary.write_text(text, encoding="utf-8"),
                            overwrite=overwrite, flag="overwrite=True")
