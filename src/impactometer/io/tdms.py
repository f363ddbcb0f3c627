"""TDMS recordings (npTDMS), laid out as LabVIEW writes waveforms.

One group holds one channel per signal; each channel carries ``wf_increment`` (sample period [s]),
``wf_start_offset`` (time of the first sample [s]), ``wf_samples`` and ``unit_string``. Metadata comes from the
file and group properties (group wins); impactometer also stores its full metadata as JSON in the file property
``impactometer_metadata``.

Read: ``group`` names the group; without it the only group, or the first group holding a force channel. Channels
of non-numeric type (strings, timestamps) are skipped.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from nptdms import ChannelObject, GroupObject, RootObject, TdmsFile, TdmsWriter

from ..errors import RecordingError
from ..recording import FORCE, Recording
from ..validation import is_real
from .channels import (
    RawData,
    merge_metadata,
    metadata_from_json,
    metadata_to_json,
    one_value,
    pick_channel,
    time_attributes,
)

GROUP = "Recording"
METADATA_PROPERTY = "impactometer_metadata"
#: properties LabVIEW puts on every waveform channel that are not metadata
WAVEFORM_PROPERTIES = ("wf_samples", "wf_start_time", "unit_string", "NI_ChannelName", "NI_UnitDescription")


def _group(tdms: TdmsFile, group: str | None, source: str):
    groups = tdms.groups()
    names = [g.name for g in groups]
    if not groups:
        raise RecordingError(f"{source}: no TDMS groups found; expected a group holding one channel per signal")
    if group is not None:
        for g in groups:
            if g.name == group:
                return g
        raise RecordingError(f"{source}: TDMS group {group!r} does not exist; groups found: {names}")
    if len(groups) == 1:
        return groups[0]
    for g in groups:
        if pick_channel([c.name for c in g.channels()], FORCE, None, option="force_channel", source=source,
                        required=False):
            return g
    raise RecordingError(f"{source}: no group holds a force channel; pass group (groups found: {names})")


#: samples of a channel read at a time (into its float64 array)
READ_BLOCK = 1 << 20


def _samples(channel) -> np.ndarray | None:
    """A numeric channel's samples as float64, read a block at a time; None for other channels."""
    dtype = getattr(channel, "dtype", None)
    size = len(channel)
    if dtype is None or np.dtype(dtype).kind not in "iuf" or size == 0:
        return None
    out = np.empty(size)
    for start in range(0, size, READ_BLOCK):
        block = np.asarray(channel[start:start + READ_BLOCK])
        if block.dtype.kind not in "iuf":
            return None
        out[start:start + block.size] = block
    return out


def read(path: Path, *, group: str | None = None) -> RawData:
    """What a TDMS file holds (read-only); channel data is read in blocks, straight into float64 arrays."""
    source = str(path)
    # the file is opened here, not by npTDMS, so that it is closed also when a damaged header stops npTDMS
    with open(path, "rb") as handle, TdmsFile.open(handle) as tdms:
        return _read(tdms, group, source)


def _read(tdms, group: str | None, source: str) -> RawData:
    node = _group(tdms, group, source)
    columns = {}
    rates, starts = set(), set()
    for channel in node.channels():
        data = _samples(channel)
        if data is None:
            continue
        props = dict(channel.properties)
        unit = props.get("unit_string")
        rate, start, _ = time_attributes({k: v for k, v in props.items() if k not in WAVEFORM_PROPERTIES},
                                         f"{source}: channel {channel.name!r}")
        if rate is not None:
            rates.add(rate)
        if start is not None:
            starts.add(start)
        columns[channel.name] = (data, None if unit in (None, "") else str(unit))
    if not columns:
        raise RecordingError(f"{source}: group {node.name!r} holds no numeric channel; channels found: "
                             f"{[c.name for c in node.channels()]}")
    if len(rates) > 1 or len(starts) > 1:
        raise RecordingError(f"{source}: channels of group {node.name!r} have different wf_increment or "
                             f"wf_start_offset ({sorted(rates)} Hz, {sorted(starts)} s); expected one time base")
    levels = [("file property", {k: v for k, v in tdms.properties.items() if k != "name"}),
              (f"group {node.name!r} property", dict(node.properties))]
    metadata = {}
    for _, level in levels:
        if METADATA_PROPERTY in level:
            metadata = metadata_from_json(level.pop(METADATA_PROPERTY), source, METADATA_PROPERTY)
    rate, start, rest = time_attributes(levels, source)
    stated = [(f"wf_increment of the channels of group {node.name!r}", r) for r in rates]
    rate = one_value(stated + ([("a file or group property", rate)] if rate is not None else []), source,
                "sample rate", "Hz", 1e-6)
    begun = [(f"wf_start_offset of the channels of group {node.name!r}", t) for t in starts]
    start = one_value(begun + ([("a file or group property", start)] if start is not None else []), source,
                 "start time", "s", 1e-9)
    return RawData(columns=columns, source=source, sample_rate=rate, start_time=start,
                   metadata=merge_metadata([("property", rest), (METADATA_PROPERTY, metadata)], source))


def write(recording: Recording, path: Path, *, group: str = GROUP) -> None:
    """Write ``recording`` as a LabVIEW-style waveform group."""
    truth = {k: float(v) for k, v in recording.metadata.items()
             if k in ("mass_kg", "velocity_m_s", "pressure_gauge_Pa") and is_real(v)}
    root = RootObject(properties={"name": Path(path).stem, METADATA_PROPERTY: metadata_to_json(recording)} | truth)
    objects = [root, GroupObject(group, properties={})]
    for name, values in recording.channels.items():
        objects.append(ChannelObject(group, name, np.asarray(values, dtype=np.float64), properties={
            "wf_increment": 1.0 / recording.sample_rate, "wf_start_offset": float(recording.start_time),
            "wf_samples": int(values.size), "unit_string": recording.unit(name),
            "NI_ChannelName": name}))
    with TdmsWriter(str(path)) as writer:
        writer.write_segment(objects)

