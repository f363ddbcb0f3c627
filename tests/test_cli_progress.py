"""Long commands say what they are doing on standard error (a spinner on a terminal; elsewhere one line, and only
when numba compiles), so that standard output keeps only results."""

from __future__ import annotations

import json

import numba

from impactometer.cli import main
from impactometer.cli.app import announce_compilation


def test_the_compile_notice_is_one_line_on_stderr_and_only_when_numba_compiles(capsys):
    @numba.njit
    def increment(x):
        return x + 1

    with announce_compilation("adding one", compile_time="about 1 s"):
        assert increment(1) == 2 and increment(1.5) == 2.5  # two compilations, one notice
    assert capsys.readouterr() == ("", "adding one: compiling kernels, first run only (about 1 s) ...\n")
    with announce_compilation("adding one"):
        assert increment(2) == 3
    assert capsys.readouterr() == ("", "")


def test_absorb_json_stays_parsable_with_its_progress_on_stderr(capsys):
    main(["absorb", "--json", "--strategy", "closed"])
    captured = capsys.readouterr()
    assert list(json.loads(captured.out)["strategies"]) == ["closed"]
    assert all(line.startswith("closed loop on drop-stand: identify M1 and V0 (model), then control valve Z with "
                               "closed: compiling kernels, first run only (about 30-80 s) ...")
               for line in captured.err.splitlines())
