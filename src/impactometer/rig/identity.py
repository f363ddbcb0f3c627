"""How a stand is known: the :func:`fingerprint` of its parameters, which a recording states under
:data:`STAND_KEY` and :func:`check_recorded_on` compares."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from typing import Any, Protocol

from ..errors import ParameterError
from ..validation import is_real
from .stand import Rig, from_dict, to_dict

#: metadata key holding the fingerprint of the stand a recording was made on
STAND_KEY = "rig_fingerprint"


class Recorded(Protocol):
    """What :func:`check_recorded_on` reads of a recording (an :class:`~impactometer.recording.Recording`)."""

    @property
    def metadata(self) -> Mapping[str, Any]: ...

    @property
    def source(self) -> str: ...


def fingerprint(rig: Rig | dict[str, Any]) -> str:
    """A short hash of every parameter of a stand (a :class:`~impactometer.rig.Rig` or its ``to_dict`` form).

    Two stands with the same parameters have the same fingerprint whatever their names (a name is a label) and
    however their numbers are written (``2e6`` or ``2000000``); any other parameter gives another fingerprint.
    """
    stand = rig if isinstance(rig, Rig) else from_dict(rig, source="stand")

    def canonical(value: Any) -> Any:  # every number as a float: 2e6 and 2000000 hash alike
        if isinstance(value, dict):
            return {k: canonical(v) for k, v in value.items()}
        return float(value) if is_real(value) else value

    data = canonical({k: v for k, v in to_dict(stand).items() if k != "name"})
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def check_recorded_on(recording: Recorded, stand: dict[str, Any], *, hint: str,
                      error: type[Exception] = ParameterError) -> None:
    """``error`` when ``recording`` states a stand (:data:`STAND_KEY`) with other parameters than ``stand``."""
    stated = recording.metadata.get(STAND_KEY)
    if stated is None:
        return
    expected = fingerprint(stand)
    if str(stated) != expected:
        name = recording.metadata.get("rig")
        raise error(f"{recording.source}: recorded on a stand{f' labelled {name!r}' if name else ''} with other "
                    f"parameters (fingerprint {str(stated)[:16]}) than the stand {stand.get('name')!r} (fingerprint "
                    f"{expected}); {hint}")
