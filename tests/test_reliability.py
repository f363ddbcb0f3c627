"""Reliability at the edges: a generated corpus of damaged recordings, stands, maps, options and output targets.

Every case must end with exit status 2 and a one-line message, or with an answer that is right or carries a
warning; never a traceback, a silently wrong answer or a lost file (the corpus and the judge:
``reliability_cases.py``, ``reliability_corpus.py``; ``scripts/reliability_fuzz.py`` prints the same as a table).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from impactometer.cli import main
from impactometer.errors import ParameterError, RecordingError
from impactometer.filters import cfc_corridor
from impactometer.identify.peak_to_peak import identify
from impactometer.model import simulate_batch
from impactometer.recording import Recording
from impactometer.rig import load_toml, save_toml
from impactometer.studies import run_study
from reliability_api import calls, fuzz
from reliability_cases import Corpus, round_trips
from reliability_corpus import judge, run

CATEGORIES = ("stream vs identify", "map of another stand", "duplicated statements", "output targets",
              "study settings", "sample rates", "map files", "truth metadata", "implausible answers",
              "smaller breaks", "stand files", "CSV structure", "recording content", "command options",
              "late trigger", "clipped acceleration", "slow acceleration errors", "map pressure", "CSV decimal style",
              "high sample rates", "special output targets", "pointing", "unit slips", "other machines",
              "clipped in a flight", "1 MHz DAQ", "bare command")
SRC = str(Path(__file__).resolve().parents[1] / "src")


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    return Corpus(tmp_path_factory.mktemp("corpus"))


@pytest.fixture(scope="module")
def cases(corpus):
    return [case for case in corpus.cases() if not case.slow]


def test_every_category_is_exercised(cases):
    assert sorted({case.category for case in cases}) == sorted(CATEGORIES)


@pytest.mark.parametrize("category", CATEGORIES)
def test_damaged_inputs_are_refused_in_one_line_or_answered_with_a_warning(category, cases):
    outcomes, failures = {}, []
    for case in (c for c in cases if c.category == category):
        outcome = run(case)
        outcomes[case.name] = outcome
        verdict, reason = judge(case, outcome, outcomes.get(case.same_as) if case.same_as else None)
        if verdict != "handled":
            failures.append(f"{case.name}: {verdict}: {reason}")
    assert not failures, "\n".join(failures)


def test_awkward_channel_names_come_back_or_are_refused_on_writing(tmp_path):
    """A CSV header cell 'a,b' made the file unreadable; an HDF5 channel 'a/b' became a subgroup that reading left
    out, silently."""
    results = round_trips(tmp_path)
    assert len(results) >= 27
    lost = [f"{case.name}: {verdict}: {reason}" for case, verdict, reason in results if verdict != "handled"]
    assert not lost, "\n".join(lost)


def test_the_stream_and_identify_agree_on_every_damaged_impact(cases):
    pairs = [(c, next(d for d in cases if d.name == c.same_as)) for c in cases if c.same_as]
    assert len(pairs) >= 10
    for stream, batch in pairs:
        a, b = run(stream), run(batch)
        assert a.code == b.code, (stream.name, a.output[-300:], b.output[-300:])


def test_bad_arguments_to_the_python_functions_raise_impactometer_errors(corpus):
    table = calls(corpus.rec, corpus.base, corpus.map, corpus.folder)
    made, failures = fuzz(table, 1500, seed=1)
    assert made == 1500 and not failures, "\n".join(failures)


@pytest.mark.parametrize("call, error, message", [
    # each raised a builtin error before (MemoryError for 745 GiB, ValueError from float(), TypeError)
    (lambda tmp: simulate_batch(np.full(10**6, 30.0), 2.0, 200e3, duration=1.0), ParameterError,
     r"would take 745.1 GiB \(1000000 scenarios × 2 channels × 50001 samples × 8 bytes\)"),
    # a duration whose sample count overflows to inf raised OverflowError from int()
    (lambda tmp: simulate_batch(np.int64(-2), 2.0, 200e3, duration=1e308), ParameterError,
     r"duration·sample_rate must give at most 5e7 samples, got 1e\+308 s"),
    (lambda tmp: cfc_corridor(60, "abc"), ParameterError, "frequency must be finite numbers >= 0 .Hz., got 'abc'"),
    (lambda tmp: save_toml(None, tmp / "stand.toml"), ParameterError, "rig must be a Rig, got NoneType"),
    (lambda tmp: load_toml(5), ParameterError, r"rig file must be a file name \(str or path\), got int"),
    (lambda tmp: run_study("peak-force", None), ParameterError, "--out must be a folder name .*got NoneType"),
    (lambda tmp: Recording(sample_rate=1e3, channels={"contact_force": [1.0, 2.0]}).channel([1]), RecordingError,
     r"a channel name must be a str, got \[1\]; channels found: \['contact_force'\]"),
])
def test_bad_arguments_found_by_the_fuzz_raise_named_impactometer_errors(tmp_path, call, error, message):
    with pytest.raises(error, match=message):
        call(tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_a_second_study_into_a_locked_folder_is_refused(tmp_path, capsys):
    holder = textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {SRC!r})
        from impactometer.studies import store
        with store.locked(__import__("pathlib").Path({str(tmp_path)!r})):
            print("held", flush=True)
            time.sleep(60)
    """)
    process = subprocess.Popen([sys.executable, "-c", holder], stdout=subprocess.PIPE, text=True)
    try:
        assert process.stdout.readline().strip() == "held"
        with pytest.raises(SystemExit) as exit_info:
            main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1"])
        captured = capsys.readouterr()
        err = captured.err
        assert exit_info.value.code == 2 and "is being written by another study run (process" in err
        assert err.startswith("error:") and err.count("\n") == 1 and "error:" not in captured.out
        assert not (tmp_path / "peak-force.csv").exists()
    finally:
        process.kill()
        process.wait()


@pytest.mark.skipif(os.name != "posix", reason="permissions of a POSIX folder")
def test_outputs_into_a_read_only_folder_are_refused_before_any_work(tmp_path):
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o555)
    prefix: list[str] = []
    if os.geteuid() == 0:  # root writes anywhere unless it drops the capability that lets it
        if not shutil.which("setpriv"):
            pytest.skip("running as root without setpriv: a read-only folder cannot be made")
        prefix = ["setpriv", "--bounding-set=-dac_override", "--inh-caps=-dac_override"]
    env = dict(os.environ, PYTHONPATH=SRC, MPLBACKEND="Agg")
    try:
        for argv in (["record", "--out", str(folder / "r.csv")], ["absorb", "--plot", str(folder / "a.png")],
                     ["study", "peak-force", "--out", str(folder / "s"), "--grid", "2"]):
            done = subprocess.run([*prefix, sys.executable, "-m", "impactometer", *argv], capture_output=True,
                                  text=True, env=env)
            errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
            assert done.returncode == 2 and len(errors) == 1 and "permission denied" in errors[0], argv
            assert "error:" not in done.stdout and "Traceback" not in done.stdout + done.stderr, argv
        assert list(folder.iterdir()) == []
    finally:
        folder.chmod(0o755)


def test_a_runaway_reference_simulation_ends_within_seconds(corpus):
    case = next(c for c in corpus.cases() if c.slow)
    verdict, reason = judge(case, run(case))
    assert verdict == "handled", reason
    assert "more than" in reason and "steps" in reason


def test_an_acceleration_in_g_read_as_m_s2_is_named_on_the_pad_stand(corpus):
    """The stage-B equations M1·(g − a2) = Fc fit an acceleration read ÷9.81 as well as the true one (reduced χ²
    1.1, M1 about 3.5 times too large); the piston's momentum over the first pulse's rise names the slip."""
    rec = corpus.rec
    slipped = Recording(sample_rate=rec.sample_rate, start_time=rec.start_time,
                        channels={"contact_force": rec.contact_force,
                                  "piston_acceleration": rec.piston_acceleration / 9.80665})
    answer = identify(slipped)
    assert any("an acceleration in g read as m/s²" in w and "--acceleration-unit g" in w for w in answer.warnings)
    assert not any("read as" in w for w in identify(rec).warnings)
