"""Output targets: a second writer to the same file, targets that are not regular files, extensions."""

from __future__ import annotations

import os

import numpy as np
import pytest

from impactometer import io as recording_io
from impactometer.errors import OutputError, ParameterError, RecordingError
from impactometer.io import write_recording
from impactometer.model import simulate
from impactometer.model.io import save_simulation
from impactometer.outputs import publish
from impactometer.recording import Recording
from impactometer.rig import Scenario
from test_cli_simulate import assert_error_line, run

RECORDING = Recording(sample_rate=1e3, channels={"contact_force": np.arange(5.0), "piston_acceleration": np.ones(5)})


def _second_writer(monkeypatch, fmt: str, target: str, content: bytes) -> None:
    """Let another writer create ``target`` after this one wrote its temporary file and before it moves it into
    place (the check at the start found the name free for both)."""
    writer = recording_io.WRITERS[fmt]

    def slow(recording, path):
        writer(recording, path)
        (path.parent / target).write_bytes(content)

    monkeypatch.setitem(recording_io.WRITERS, fmt, slow)


@pytest.mark.parametrize("name, taken", [("run.csv", "run.csv"), ("run.csv", "run.json"), ("run.h5", "run.h5")])
def test_a_second_writer_to_the_same_file_is_refused_not_silently_replaced(tmp_path, monkeypatch, name, taken):
    # before, both writers reported success and the last rename replaced the other's file
    _second_writer(monkeypatch, recording_io.format_of(tmp_path / name), taken, b"the other writer's")
    with pytest.raises(OutputError, match="it was created while this file was being written"):
        write_recording(RECORDING, tmp_path / name)
    assert (tmp_path / taken).read_bytes() == b"the other writer's"
    assert sorted(p.name for p in tmp_path.iterdir()) == [taken]  # nothing half-placed, no temporary left


def test_with_overwrite_the_replacement_is_intended(tmp_path, monkeypatch):
    _second_writer(monkeypatch, "hdf5", "run.h5", b"the other writer's")
    write_recording(RECORDING, tmp_path / "run.h5", overwrite=True)
    assert recording_io.read_recording(tmp_path / "run.h5").channels.keys() == RECORDING.channels.keys()


def test_publish_keeps_an_existing_target_and_replaces_it_only_when_asked(tmp_path):
    target, temporary = tmp_path / "a.h5", tmp_path / ".a.partial.h5"
    target.write_text("first")
    temporary.write_text("second")
    with pytest.raises(OutputError, match="pass --overwrite to replace it"):
        publish(temporary, target, overwrite=False)
    assert target.read_text() == "first" and temporary.exists()
    publish(temporary, target, overwrite=True)
    assert target.read_text() == "second" and not temporary.exists()
    temporary.write_text("third")
    publish(temporary, tmp_path / "b.h5", overwrite=False)
    assert (tmp_path / "b.h5").read_text() == "third" and not temporary.exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes of POSIX")
def test_targets_that_are_not_regular_files_are_refused_even_with_overwrite(tmp_path, capsys):
    # before, the rename replaced a device node (mknod null.h5 c 1 3; record --out null.h5 --force) with a file
    pipe = tmp_path / "pipe.h5"
    os.mkfifo(pipe)
    device = tmp_path / "null.csv"
    device.symlink_to(os.devnull)
    for target in (pipe, device):
        with pytest.raises(RecordingError, match="is not a regular file"):
            write_recording(RECORDING, target, overwrite=True)
        status, out, err = run(["record", "--out", str(target), "--force", "--duration", "5ms"], capsys)
        assert_error_line(status, out, err)
        assert str(target) in err and "is not a regular file" in err
    assert pipe.is_fifo() and device.is_symlink() and os.path.realpath(device) == os.path.realpath(os.devnull)
    with pytest.raises(OutputError, match="is not a regular file"):
        publish(tmp_path / "missing", pipe, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["null.csv", "pipe.h5"]


def test_simulation_histories_go_to_hdf5_files_only(tmp_path, capsys):
    status, out, err = run(["simulate", "--duration", "5ms", "--out", str(tmp_path / "run.csv")], capsys)
    errors = [line for line in err.splitlines() if "compiling kernels" not in line]  # said once, on a fresh cache
    assert status == 2 and len(errors) == 1 and errors[0].startswith("error:"), err
    assert "has extension '.csv'; expected one of .h5, .hdf5" in err
    result = simulate(Scenario(mass=30.0, velocity=2.0), duration=0.005)
    with pytest.raises(ParameterError, match="expected one of .h5, .hdf5"):
        save_simulation(result, tmp_path / "run.mat")
    save_simulation(result, tmp_path / "run.h5")
    with pytest.raises(ParameterError, match="exists; pass overwrite=True"):
        save_simulation(result, tmp_path / "run.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]
