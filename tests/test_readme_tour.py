"""The README's tour runs verbatim, in order, in an empty folder, and each command gives a sensible result; its
Python snippet runs as written."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

import impactometer
from impactometer.cli.app import with_uncertainty

README = Path(__file__).resolve().parents[1] / "README.md"


def tour_commands() -> list[str]:
    """The lines of the ```bash block under '## A tour', comments removed."""
    text = README.read_text(encoding="utf-8")
    block = re.search(r"^## A tour\s*```bash\n(.*?)^```", text, flags=re.S | re.M)
    assert block, "README.md has no ```bash block under '## A tour'"
    return [shlex.split(line, comments=True) for line in block.group(1).splitlines() if line.strip()]


def python_snippet() -> str:
    """The README's ```python block."""
    block = re.search(r"^```python\n(.*?)^```", README.read_text(encoding="utf-8"), flags=re.S | re.M)
    assert block, "README.md has no ```python block"
    return block.group(1)


def test_tour_block_is_found():
    commands = tour_commands()
    assert len(commands) >= 8 and all(c[0] == "impactometer" for c in commands)


@pytest.mark.slow
def test_readme_tour_runs_verbatim(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join([str(Path(impactometer.__file__).parents[1]),
                                           os.environ.get("PYTHONPATH", "")]))
    outputs = {}
    for argv in tour_commands():
        done = subprocess.run([sys.executable, "-m", "impactometer", *argv[1:]], cwd=tmp_path, env=env,
                              capture_output=True, text=True, stdin=subprocess.DEVNULL)
        assert done.returncode == 0, f"{shlex.join(argv)} failed:\n{done.stdout}\n{done.stderr}"
        outputs[shlex.join(argv)] = done.stdout
    # the file the tour records starts at first contact and is identified: 30 kg at 1.98 m/s, 1 % noise
    robust = json.loads(outputs["impactometer identify drop.tdms --json"])
    assert abs(robust["mass_kg"] / 30.0 - 1) < 0.05 and abs(robust["velocity_m_s"] / 1.981 - 1) < 0.02
    stream_final = [line for line in outputs["impactometer stream drop.tdms --realtime"].splitlines()
                    if "estimate" in line][-1]
    # the stream's last estimate is the batch's final answer
    assert with_uncertainty(robust["mass_kg"], robust["mass_std_kg"], "kg") in stream_final
    paper = outputs["impactometer identify drop.tdms --variant paper"]
    assert "caution" in paper  # 1 % noise: the paper's noise-free assumption does not hold
    for name in ("impactometer-demo/impact.png", "impactometer-demo/absorb.png", "run.h5", "run.png", "drop.tdms",
                 "drop.png", "map.h5", "fig10.png", "studies/index.html", "lab.toml"):
        assert (tmp_path / name).exists(), name
    # the stand calibrated from six drops: a figure per drop and the held-back drop's; that drop identified with it
    assert len(list((tmp_path / "calibration").glob("*.png"))) >= 7
    assert list((tmp_path / "validation").glob("*.png"))
    held = json.loads(outputs["impactometer identify held18.h5 --method model --rig lab.toml --json"])
    assert abs(held["mass_kg"] - 18.0) < 4.0 * held["mass_std_kg"] + 0.01 * 18.0


@pytest.mark.slow
def test_readme_python_snippet_runs_as_written(tmp_path, monkeypatch):
    """The snippet runs in an empty folder and writes only there: the answer it identifies is the impact it
    recorded, and the stand it calibrates from six drops is one for each drop and can be saved."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    names: dict = {}
    exec(compile(python_snippet(), str(README), "exec"), names)  # noqa: S102  (the README's own code)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lab-base.toml"]
    assert names["answer"].error is None and abs(names["answer"].mass / 30.0 - 1) < 0.1
    lab = names["lab"]
    assert len(lab.drops) == 6 and lab.to_toml(tmp_path / "lab.toml").is_file()
