"""``impactometer study``: in-process CLI runs, files written, errors in one line with exit status 2."""

from __future__ import annotations

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
    assert code == 2 and "other options" in out and "--force" in out
    main(["study", "peak-force", "--out", str(tmp_path), "--grid", "2", "--workers", "1", "--seed", "3", "--force"])


@pytest.mark.parametrize("argv, message", [
    (["study", "nope", "--out", "x"], "study must be one of"),
    (["study", "peak-force"], "--out is required"),
    (["study", "peak-force", "--out", "x", "--noise", "3kg"], "--noise"),
    (["study", "peak-force", "--out", "x", "--grid", "1"], r"grid must be an integer within [2, 40]"),
    (["study", "peak-force", "--out", "x", "--grid", "1000"], r"grid must be an integer within [2, 40]"),
    (["study", "peak-force", "--out", "x", "--set", "chunk_size=3"], "--set must look like STUDY.SETTING=VALUE"),
    (["study", "peak-force", "--out", "x", "--contact", "glue"], "contact.law must be one of"),
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
                   "import impactometer.studies.runner as runner\n"
                   "evaluate = runner.evaluate_chunk\n"
                   "def slow(*args, **kwargs):\n"
                   "    time.sleep(0.02)\n"
                   "    return evaluate(*args, **kwargs)\n"
                   "runner.evaluate_chunk = slow\n"
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
