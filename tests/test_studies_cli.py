"""``impactometer study``: in-process CLI runs, files written, errors in one line with exit status 2."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from impactometer.cli import main


def _run(argv, capsys):
    """Run a command that must fail; return (exit status, its one error line from stderr), with stdout free of it."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    captured = capsys.readouterr()
    assert "error:" not in captured.out and "Traceback" not in captured.out + captured.err, captured
    assert captured.err.startswith("error:") and captured.err.count("\n") == 1, captured.err
    return exc.value.code, captured.err


def test_study_writes_table_figure_and_report(tmp_path, capsys):
    main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1", "--contact", "hunt"])
    out = capsys.readouterr().out
    assert "report written to" in out
    for name in ("peak-force.csv", "peak-force.png", "index.html"):
        assert (tmp_path / name).stat().st_size > 0
    assert (tmp_path / "peak-force.csv").read_text().count("hunt-crossley") == 8
    # rerun: everything reused
    main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1", "--contact", "hunt"])
    assert "1/1" in capsys.readouterr().out


def test_other_options_need_force(tmp_path, capsys):
    main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1"])
    capsys.readouterr()
    code, out = _run(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1",
                      "--seed", "3"], capsys)
    assert code == 2 and "other options" in out and "--overwrite" in out
    main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1", "--seed", "3", "--overwrite"])


@pytest.mark.parametrize("argv, message", [
    (["study", "nope", "--out", "x"], "study must be one of"),
    (["study", "peak-force"], "--out is required"),
    (["study", "peak-force", "--out", "x", "--noise", "3kg"], "--noise"),
    (["study", "peak-force", "--out", "x", "--grid", "1"], "--grid 1: must be an integer within [2, 40]"),
    (["study", "peak-force", "--out", "x", "--grid", "1000"], "--grid 1000: must be an integer within [2, 40]"),
    (["study", "peak-force", "--out", "x", "--set", "chunk_size=3"], "--set must look like STUDY.SETTING=VALUE"),
    (["study", "peak-force", "--out", "x", "--contact", "glue"], "--contact glue: must be one of"),
])
def test_bad_input_is_one_line_and_exit_2(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out = _run(argv, capsys)
    assert code == 2
    assert message in out and "Traceback" not in out
    assert not (tmp_path / "x").exists()


def test_list_shows_every_study(capsys):
    main(["study", "list"])
    out = capsys.readouterr().out
    assert "peak-force" in out and "noise" in out and "sampling" in out


def test_report_rebuilds_the_page_and_prints_markdown(tmp_path, capsys):
    main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1"])
    (tmp_path / "index.html").unlink()
    capsys.readouterr()
    main(["study", "report", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert (tmp_path / "index.html").exists()
    assert "| peak-force | 8 | 8 | 1 |" in out and "| total |" in out and "| study | quantity | ours | paper |" in out


def test_ctrl_c_exits_130_and_keeps_finished_chunks(tmp_path):
    import json
    import signal
    import subprocess
    import sys
    import time

    # every chunk takes at least 20 ms, so the interrupt lands mid-run however fast the machine is; Ctrl-C raises
    # KeyboardInterrupt as in a terminal, also where the test runs under a shell that started it with SIGINT ignored
    slow_chunks = ("import signal\n"
                   "import time\n"
                   "signal.signal(signal.SIGINT, signal.default_int_handler)\n"
                   "import impactometer.studies.executors as executors\n"
                   "evaluate = executors.evaluate_chunk\n"
                   "def slow(*args, **kwargs):\n"
                   "    time.sleep(0.02)\n"
                   "    return evaluate(*args, **kwargs)\n"
                   "executors.evaluate_chunk = slow\n"
                   "from impactometer.cli import main\n"
                   "main()\n")
    command = [sys.executable, "-c", slow_chunks, "study", "peak-force", "--out",
               str(tmp_path), "--workers", "1", "--grid", "7", "--set", "peak-force.chunk_size=1"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(list((tmp_path / "peak-force").glob("chunk-*.json"))) < 3:
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130, out
    assert "interrupted: the finished chunks are kept" in out and "Traceback" not in out
    chunks = list((tmp_path / "peak-force").glob("chunk-*.json"))
    assert 3 <= len(chunks) < 7**3 and all(json.loads(p.read_text())["rows"] for p in chunks)


# a study whose chunks never end: each worker writes a marker (its process id) next to the script, then waits for
# ever, so the run can only end by being stopped. The script is the main module: spawned workers import it too, so
# the patch applies in them.
BLOCKING_CHUNKS = """\
import os
import pathlib
import threading

import impactometer.studies.executors as executors

MARKERS = pathlib.Path(__file__).with_name("markers")


def blocking_chunk(name, cases, options):
    (MARKERS / str(os.getpid())).write_text("")
    threading.Event().wait()


executors.evaluate_chunk = blocking_chunk

if __name__ == "__main__":
    from impactometer.cli import main

    main()
"""
HANG_GUARD = 300  # [s] only a hung run gets near it


def _process_state(pid):
    """The state letter of process ``pid`` (R, S, Z, ...), None when there is none."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return None


def _children(pid):
    """Process ids of the children of ``pid``."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rpartition(")")[2].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _gone(pids):
    """Whether no process of ``pids`` runs any more (a zombie waiting for its reaper has ended)."""
    return all(_process_state(pid) in (None, "Z", "X") for pid in pids)


def _until(condition, what):
    """Poll ``condition()`` until true; fail after HANG_GUARD seconds (a hang, not a slow machine)."""
    deadline = time.monotonic() + HANG_GUARD
    while not condition():
        assert time.monotonic() < deadline, f"still waiting after {HANG_GUARD} s for {what}"
        time.sleep(0.02)


def _blocked_study(tmp_path):
    """A `study` process with two workers, each blocked in its first chunk: (process, its children, out folder)."""
    script = tmp_path / "blocking_study.py"
    script.write_text(BLOCKING_CHUNKS)
    (tmp_path / "markers").mkdir()
    out = tmp_path / "out"
    command = [sys.executable, str(script), "study", "peak-force", "--out", str(out), "--workers", "2", "--grid", "2",
               "--set", "peak-force.chunk_size=1"]
    log = (tmp_path / "log.txt").open("w")
    proc = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, text=True,
                            env={**os.environ, "MPLBACKEND": "Agg"})

    def workers_blocked():
        assert proc.poll() is None, (tmp_path / "log.txt").read_text()
        return len(list((tmp_path / "markers").iterdir())) == 2

    _until(workers_blocked, "two workers in their first chunk")
    workers = {int(p.name) for p in (tmp_path / "markers").iterdir()}
    children = set(_children(proc.pid))
    assert workers <= children  # the workers and the resource tracker of multiprocessing
    return proc, children, out


LINUX = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads processes from /proc")


@LINUX
def test_sigterm_stops_the_workers_and_removes_the_lock(tmp_path):
    proc, children, out = _blocked_study(tmp_path)
    assert (out / ".impactometer.lock").read_text() == f"process {proc.pid}"
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=HANG_GUARD) == 128 + signal.SIGTERM, (tmp_path / "log.txt").read_text()
    assert "interrupted: the finished chunks are kept" in (tmp_path / "log.txt").read_text()
    _until(lambda: _gone(children), f"the children {sorted(children)} to end")
    assert not (out / ".impactometer.lock").exists()


@LINUX
def test_sigkill_of_the_parent_ends_its_workers_and_a_rerun_takes_over_the_lock(tmp_path, capsys):
    proc, children, out = _blocked_study(tmp_path)
    proc.kill()
    proc.wait(timeout=HANG_GUARD)
    _until(lambda: _gone(children), f"the orphaned children {sorted(children)} to end")
    assert (out / ".impactometer.lock").read_text() == f"process {proc.pid}"  # a killed run cannot clean up
    main(["study", "peak-force", "--out", str(out), "--workers", "1", "--grid", "2",
          "--set", "peak-force.chunk_size=1"])
    err = capsys.readouterr().err
    assert f"note: removed a stale lock {str(out / '.impactometer.lock')!r} of process {proc.pid}, which is no " \
           "longer running" in err
    assert (out / "peak-force.csv").exists() and not (out / ".impactometer.lock").exists()


def test_a_rerun_keeps_finished_studies_and_force_rewrites_them(tmp_path, capsys):
    argv = ["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1"]
    main(argv)
    capsys.readouterr()
    files = [tmp_path / name for name in ("peak-force.csv", "peak-force.png", "index.html")]
    before = [path.stat() for path in files]
    main(argv)
    out = capsys.readouterr().out
    assert "kept (finished earlier)" in out and "report" in out and "kept (--overwrite rewrites them)" in out
    assert [(s.st_ino, s.st_mtime_ns) for s in before] == [(p.stat().st_ino, p.stat().st_mtime_ns) for p in files]
    # a lost figure is drawn again (from the kept chunks), and the report rewritten; the table stays
    files[1].unlink()
    main(argv)
    assert "report written to" in capsys.readouterr().out and files[1].exists()
    assert files[0].stat().st_ino == before[0].st_ino and files[2].stat().st_ino != before[2].st_ino
    main([*argv, "--overwrite"])
    assert "report written to" in capsys.readouterr().out
    assert all(p.stat().st_ino != s.st_ino for p, s in zip(files, before, strict=True))


def test_progress_goes_to_stderr_as_lines_where_it_is_not_a_terminal(tmp_path, capsys):
    handler = signal.getsignal(signal.SIGTERM)
    main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1",
          "--set", "peak-force.chunk_size=2"])
    captured = capsys.readouterr()
    assert "peak-force: 0/8" not in captured.out and "study" in captured.out
    lines = captured.err.splitlines()
    assert lines[0] == "peak-force: 0/8 cases (0 s)" and lines[-1].startswith("peak-force: 8/8 cases done (")
    assert [line.split(" (")[0] for line in lines if "/8 cases" in line] == [
        f"peak-force: {n}/8 cases" + (" done" if n == 8 else "") for n in (0, 2, 4, 6, 8)]
    assert "\x1b" not in captured.err and "\r" not in captured.err
    assert signal.getsignal(signal.SIGTERM) == handler  # SIGTERM stops a study only while it runs
