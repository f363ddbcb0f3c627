"""Study runner: determinism over workers and seeds, resumable chunks, SIGKILL safety, option checks."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from impactometer.errors import ParameterError
from impactometer.studies import StudyOptions, executors, run_study
from impactometer.studies.executors import compiling
from impactometer.studies.store import LOCK, atomic_write, locked, read_chunk
from impactometer.tables import read_csv

SMALL = dict(grid=3, params={"peak-force.chunk_size": 4})  # 27 cases in 7 chunks


def test_same_table_whatever_the_number_of_workers(tmp_path):
    one = run_study("peak-force", tmp_path / "one", StudyOptions(**SMALL), workers=1)
    two = run_study("peak-force", tmp_path / "two", StudyOptions(**SMALL), workers=2)
    assert one.chunks == 7 and one.cases == 27
    assert one.table.read_text() == two.table.read_text()


def test_seed_changes_the_noise_and_nothing_else(tmp_path):
    a = run_study("peak-force", tmp_path / "a", StudyOptions(seed=1, **SMALL), workers=1).rows
    b = run_study("peak-force", tmp_path / "b", StudyOptions(seed=2, **SMALL), workers=1).rows
    assert [r["simulated_peak_force"] for r in a] == [r["simulated_peak_force"] for r in b]
    recorded_a = np.array([r["recorded_peak_force"] for r in a])
    recorded_b = np.array([r["recorded_peak_force"] for r in b])
    assert np.all(recorded_a != recorded_b)
    # 1 % noise on a peak of a few kN moves the recorded peak by a few percent at most
    np.testing.assert_allclose(recorded_a, recorded_b, rtol=0.05)


def test_rerun_reuses_finished_chunks_and_recomputes_damaged_ones(tmp_path):
    first = run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1)
    folder = tmp_path / "peak-force"
    # a truncated chunk under the final name (as a non-atomic writer could leave) and a stray temporary file
    text = (folder / "chunk-00002.json").read_text()
    (folder / "chunk-00002.json").write_text(text[: len(text) // 2])
    (folder / ".chunk-00003.json.abc.tmp").write_text("{")
    second = run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1)
    assert second.reused_chunks == first.chunks - 1
    assert second.table.read_text() == first.table.read_text()
    chunk = json.loads((folder / "chunk-00002.json").read_text())
    assert [c["case"] for c in chunk["cases"]] == [8, 9, 10, 11]
    key = StudyOptions(**SMALL).key("peak-force")
    assert read_chunk(folder, study="peak-force", key=key, index=2, cases=chunk["cases"]) is not None
    other = [{**c, "mass": c["mass"] + 1.0} for c in chunk["cases"]]  # same indices, other scenarios
    assert read_chunk(folder, study="peak-force", key=key, index=2, cases=other) is None


def test_other_options_in_the_same_folder_need_force(tmp_path):
    run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1)
    with pytest.raises(ParameterError, match="other options.*--overwrite"):
        run_study("peak-force", tmp_path, StudyOptions(seed=5, **SMALL), workers=1)
    redone = run_study("peak-force", tmp_path, StudyOptions(seed=5, **SMALL), workers=1, force=True)
    assert redone.reused_chunks == 0


def test_a_table_not_written_by_a_study_is_not_overwritten(tmp_path):
    (tmp_path / "peak-force.csv").write_text("mine\n")
    with pytest.raises(ParameterError, match="not written by a study run"):
        run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1)
    assert (tmp_path / "peak-force.csv").read_text() == "mine\n"


def test_killed_run_loses_no_finished_chunk_and_resumes(tmp_path):
    out = tmp_path / "killed"
    options = StudyOptions(grid=3, params={"peak-force.chunk_size": 1})  # 27 one-case chunks
    command = [sys.executable, "-c", "from impactometer.cli import main; main()", "study", "peak-force",
               "--out", str(out), "--workers", "1", "--grid", "3", "--set", "peak-force.chunk_size=1"]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    folder = out / "peak-force"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(list(folder.glob("chunk-*.json"))) < 5:
        time.sleep(0.005)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    chunks = sorted(folder.glob("chunk-*.json"))
    assert 5 <= len(chunks) < 27, "the run must be killed part-way"
    assert not (out / "peak-force.csv").exists()
    for path in chunks:  # every file under a final name is complete
        assert json.loads(path.read_text())["rows"]
    with pytest.warns(UserWarning, match=rf"removed a stale lock .* of process {proc.pid}, which is no longer running"):
        resumed = run_study("peak-force", out, options, workers=1)
    assert resumed.reused_chunks >= len(chunks)
    fresh = run_study("peak-force", tmp_path / "fresh", options, workers=1)
    assert read_csv(resumed.table.read_text()) == read_csv(fresh.table.read_text())


def test_atomic_write_replaces_whole_files(tmp_path):
    path = tmp_path / "t.csv"
    atomic_write(path, "a,b\n1,2\n")
    atomic_write(path, "a,b\n3,4\n")
    assert path.read_text() == "a,b\n3,4\n"
    assert [p.name for p in tmp_path.iterdir()] == ["t.csv"]


@pytest.mark.parametrize("kwargs, match", [
    ({"grid": 1}, r"grid must be an integer within \[2, 40\], got 1"),
    ({"grid": 1000}, r"grid must be an integer within \[2, 40\], got 1000"),
    ({"seeds": 0}, r"seeds must be an integer within \[1, 100\]"),
    ({"grid": 40, "seeds": 10}, "grid³ × seeds must be at most 200000 scenarios"),
    ({"seed": -1}, r"seed must be an integer within \[0, "),
    ({"params": {"noise.levels": []}}, "--set noise.levels must hold 1 to 100 values, got 0"),
    ({"params": {"noise.levels": [-1]}}, r"--set noise.levels must lie within \[0, 1\], got -1"),
    ({"params": {"noise.levels": [float("nan")]}}, "--set noise.levels must be a finite number"),
    ({"params": {"noise.levels": "abc"}}, "--set noise.levels must be a number with an optional fraction unit"),
    ({"params": {"peak-force.nope": 1}}, "unknown setting 'peak-force.nope'; study 'peak-force' has"),
    ({"params": {"sampling.rates": ["1GHz"]}}, r"--set sampling.rates must lie within \[5000, 1e\+06\] Hz"),
    ({"params": {"map-size.sizes": [2.5]}}, "--set map-size.sizes must be an integer, got 2.5"),
    ({"params": {"absorption.identification": "response-map"}}, "must be one of"),
    ({"noise": 2.0}, r"noise must be a number within \[0, 1\]"),
    ({"sample_rate": float("nan")}, "sample_rate must be a number"),
    ({"rig": "drop-stand"}, "rig must be a Rig"),
])
def test_options_are_validated(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        StudyOptions(**kwargs)


def test_unknown_study_and_bad_executor_options(tmp_path):
    with pytest.raises(ParameterError, match="study must be one of .*peak-force"):
        run_study("nope", tmp_path)
    with pytest.raises(ParameterError, match="--workers must be an integer >= 1"):
        run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=0)
    with pytest.raises(ParameterError, match="--scheduler must be an address"):
        run_study("peak-force", tmp_path / "s", StudyOptions(**SMALL), scheduler="localhost")
    with pytest.raises(ParameterError, match=r"--set peak-force.chunk_size must lie within \[1, 100000\], got 0"):
        run_study("peak-force", tmp_path / "c", StudyOptions(grid=2, params={"peak-force.chunk_size": 0}))


def test_a_failing_chunk_names_its_study_and_cases_and_keeps_finished_chunks(tmp_path, monkeypatch):
    from impactometer.errors import SimulationError
    from impactometer.studies import STUDIES, get_study, load_studies

    load_studies()

    study = get_study("peak-force")
    original = study.evaluate

    def flaky(cases, options):
        if cases[0]["case"] >= 8:
            raise SimulationError("integrator failed")
        return original(cases, options)

    monkeypatch.setitem(STUDIES, "peak-force", dataclasses.replace(study, evaluate=flaky))
    with pytest.raises(SimulationError, match=r"study 'peak-force', cases 8-11: integrator failed"):
        run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1)
    assert len(list((tmp_path / "peak-force").glob("chunk-*.json"))) == 2
    assert not (tmp_path / "peak-force.csv").exists()


def test_the_lock_is_removed_however_the_run_ends(tmp_path, monkeypatch):
    run_study("peak-force", tmp_path / "done", StudyOptions(**SMALL), workers=1)
    assert not (tmp_path / "done" / LOCK).exists()
    with pytest.raises(ParameterError, match="other options"):
        run_study("peak-force", tmp_path / "done", StudyOptions(seed=9, **SMALL), workers=1)
    assert not (tmp_path / "done" / LOCK).exists()

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(executors, "evaluate_chunk", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_study("peak-force", tmp_path / "stopped", StudyOptions(**SMALL), workers=1)
    assert not (tmp_path / "stopped" / LOCK).exists()


def test_a_lock_left_by_a_dead_process_is_stale_and_said_so(tmp_path):
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                           check=True)
    dead = int(ended.stdout)
    (tmp_path / LOCK).write_text(f"process {dead}")
    notes = []
    with locked(tmp_path, notice=notes.append):
        assert (tmp_path / LOCK).read_text() == f"process {os.getpid()}"
    assert notes == [f"removed a stale lock {str(tmp_path / LOCK)!r} of process {dead}, which is no longer running "
                     "(a killed run; its finished chunks are kept)"]
    (tmp_path / LOCK).write_text(f"process {os.getppid()}")  # running, but holding no lock on the file
    with locked(tmp_path, notice=notes.append):
        pass
    assert "which no longer holds it" in notes[-1] and not (tmp_path / LOCK).exists()


def test_a_rerun_keeps_a_finished_study_and_force_rewrites_it(tmp_path):
    first = run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1)
    stats = [path.stat() for path in (first.table, first.figure)]
    again = run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1)
    assert again.kept and again.reused_chunks == again.chunks and again.rows == first.rows
    assert [(s.st_ino, s.st_mtime_ns) for s in stats] == [(p.stat().st_ino, p.stat().st_mtime_ns)
                                                          for p in (again.table, again.figure)]
    forced = run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=1, force=True)
    assert not forced.kept and forced.table.stat().st_ino != stats[0].st_ino
    assert forced.table.read_text() == first.table.read_text()


def test_compiling_calls_back_once_when_numba_compiles_and_not_for_a_compiled_kernel():
    import numba

    @numba.njit
    def twice(x):
        return 2 * x

    calls = []
    with compiling(lambda: calls.append("compiling")):
        assert twice(2) == 4 and twice(2.5) == 5.0  # two signatures, two compilations, one call
    assert calls == ["compiling"]
    with compiling(lambda: calls.append("again")):
        assert twice(3) == 6
    assert calls == ["compiling"]


def test_a_pool_says_what_it_does_until_its_first_chunk_lands(tmp_path):
    said = []
    run_study("peak-force", tmp_path, StudyOptions(**SMALL), workers=2, status=lambda name, text: said.append(text))
    doing = {"starting 2 worker processes", "running the first chunks",
             f"compiling kernels in 2 workers (first run only, {executors.COMPILE_TIME})"}
    assert said[0] in doing and said[-1] == "" and set(said) <= doing | {""}
