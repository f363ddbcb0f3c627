"""Property-based tests: random bytes, corrupted files and well-formed-but-wrong tables thrown at every reader.

Whatever the input, a reader returns a Recording or raises a RecordingError: never another exception.
"""

import tempfile
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

from impactometer.errors import RecordingError
from impactometer.io import read_recording, write_recording
from impactometer.recording import Recording

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
EXTENSIONS = (".csv", ".h5", ".tdms", ".mat")
MAGIC = {".csv": b"time [s],force [N]\n", ".h5": b"\x89HDF\r\n\x1a\n", ".tdms": b"TDSm",
         ".mat": b"MATLAB 5.0 MAT-file".ljust(124) + b"\x00\x01IM"}


def _read(path: Path, **options):
    try:
        result = read_recording(path, **options)
    except RecordingError:
        return None
    assert isinstance(result, Recording)
    return result


def _valid_bytes(ext: str) -> bytes:
    rng = np.random.default_rng(1)
    rec = Recording(sample_rate=1e4, channels={"contact_force": rng.random(30), "piston_acceleration":
                                               rng.normal(size=30)}, metadata={"mass_kg": 3.0})
    with tempfile.TemporaryDirectory() as folder:
        path = write_recording(rec, Path(folder) / f"v{ext}")
        return path.read_bytes()


VALID = {ext: _valid_bytes(ext) for ext in EXTENSIONS}


@pytest.mark.parametrize("ext", EXTENSIONS)
@FUZZ
@given(data=st.binary(max_size=3000), magic=st.booleans())
def test_random_bytes(ext, data, magic):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"f{ext}"
        path.write_bytes((MAGIC[ext] if magic else b"") + data)
        _read(path)


@pytest.mark.parametrize("ext", EXTENSIONS)
@FUZZ
@given(data=st.data())
def test_corrupted_valid_files(ext, data):
    raw = bytearray(VALID[ext])
    cut = data.draw(st.integers(0, len(raw)), label="length")
    edits = data.draw(st.lists(st.tuples(st.integers(0, max(len(raw) - 1, 0)), st.integers(0, 255)), max_size=8))
    for position, value in edits:
        raw[position] = value
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"f{ext}"
        path.write_bytes(bytes(raw[:cut]))
        _read(path)


NAMES = st.sampled_from(["time [s]", "t (ms)", "Force [kN]", "force [m]", "Acc (g)", "a2", "Fc [N]", "x",
                         "Temperature [degC]", "", "time", "Force [kN]", "acc [bogus]"])
CELLS = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-5, 5).map(str),
                  st.sampled_from(["", "abc", "1,5", "nan", "-inf", "1e400", " ", '"q"']))


@FUZZ
@given(header=st.lists(NAMES, min_size=1, max_size=5), rows=st.lists(st.lists(CELLS, max_size=6), max_size=8),
       separator=st.sampled_from([",", ";", "\t"]), sidecar=st.sampled_from([None, "{}", "[", '{"sample_rate": 0}',
                                                                             '{"sample_rate": 1000}', '"x"']))
def test_wrong_csv_tables(header, rows, separator, sidecar):
    text = separator.join(header) + "\n" + "\n".join(separator.join(row) for row in rows)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "t.csv"
        path.write_text(text)
        if sidecar is not None:
            (Path(folder) / "t.json").write_text(sidecar)
        _read(path)
        _read(path, sample_rate=1e3, force_channel="x")


ARRAYS = st.one_of(
    st.integers(0, 12).map(lambda n: np.linspace(0, 1, n)),
    st.integers(1, 6).map(lambda n: np.full((n, 2), 1.0)),
    st.just(np.array([1, 2, 3], dtype=np.int16)),
    st.just(np.array([np.nan, 1.0, 2.0])),
    st.just(np.array([b"a", b"b"])),
    st.floats(allow_nan=True).map(lambda x: np.array(x)),
)
ATTRS = st.dictionaries(st.sampled_from(["fs", "dt", "sample_rate", "start_time", "metadata", "mass_kg", "unit",
                                         "wf_increment"]),
                        st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=5),
                                  st.just(np.arange(3.0)), st.integers(-3, 3)), max_size=4)
DATASET_NAMES = st.sampled_from(["force", "Force [kN]", "acc", "time", "Fc", "other", "a2 (g)"])


@FUZZ
@given(datasets=st.dictionaries(DATASET_NAMES, st.tuples(ARRAYS, ATTRS), max_size=4), attrs=ATTRS,
       in_group=st.booleans())
def test_wrong_hdf5_content(datasets, attrs, in_group):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "t.h5"
        with h5py.File(path, "w") as handle:
            node = handle.create_group("g") if in_group else handle
            for key, value in attrs.items():
                node.attrs[key] = value
            for name, (array, ds_attrs) in datasets.items():
                ds = node.create_dataset(name, data=array)
                for key, value in ds_attrs.items():
                    ds.attrs[key] = value
        _read(path)
        _read(path, group="g")


TDMS_PROPS = st.dictionaries(st.sampled_from(["wf_increment", "wf_start_offset", "unit_string", "mass_kg", "fs"]),
                             st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=4),
                                       st.integers(-2, 2)), max_size=3)


@FUZZ
@given(channels=st.lists(st.tuples(DATASET_NAMES, st.one_of(
    st.integers(0, 10).map(lambda n: np.linspace(-1, 1, n)), st.just(np.array([1, 2], dtype=np.int32)),
    st.just(np.array(["s", "t"]))), TDMS_PROPS), max_size=4), groups=st.lists(st.sampled_from(["A", "B"]),
                                                                             min_size=0, max_size=2, unique=True),
    root=TDMS_PROPS)
def test_wrong_tdms_content(channels, groups, root):
    objects = [RootObject(properties=root)] + [GroupObject(g) for g in groups]
    seen = set()
    for i, (name, data, props) in enumerate(channels):
        group = groups[i % len(groups)] if groups else "A"
        if (group, name) in seen:
            continue
        seen.add((group, name))
        objects.append(ChannelObject(group, name, data, properties=props))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "t.tdms"
        try:
            with TdmsWriter(str(path)) as writer:
                writer.write_segment(objects)
        except (TypeError, ValueError):
            return  # npTDMS cannot write this property type: nothing to read
        _read(path)
        _read(path, group="B")


@FUZZ
@given(variables=st.dictionaries(st.sampled_from(["force", "acc", "time", "fs", "dt", "units", "metadata_json",
                                                  "s", "Fc"]),
                                 st.one_of(ARRAYS, st.text(max_size=6), st.floats(allow_nan=True),
                                           st.just({"force": "kN", "acc": 3.0}),
                                           st.just({"force": np.arange(4.0), "fs": 1e3})), max_size=5))
def test_wrong_mat_content(variables):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "t.mat"
        try:
            scipy.io.savemat(path, variables)
        except (TypeError, ValueError):
            return
        _read(path)
