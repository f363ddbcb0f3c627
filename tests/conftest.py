"""Shared fixtures: the built-in stand and a stand reduced to two free bodies; the hypothesis profiles; every test
in an empty folder of its own, and a suite that leaves no file behind in the working tree."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import matplotlib
import pytest
from hypothesis import settings

from impactometer.rig import get_rig

matplotlib.use("Agg")
# "ci" (the default): the same examples on every run, so a property test cannot fail on one run and pass on the next;
# "dev" (HYPOTHESIS_PROFILE=dev): hypothesis' own defaults, fresh random examples each run
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("dev")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


ROOT = Path(__file__).resolve().parents[1]
_TREE = pytest.StashKey[set[str] | None]()


def _untracked_files() -> set[str] | None:
    """The files git neither tracks nor ignores in the checkout the tests run in (None outside a git checkout)."""
    try:
        done = subprocess.run(["git", "ls-files", "--others", "--exclude-standard"], cwd=ROOT,
                              capture_output=True, text=True, check=False)
    except OSError:
        return None
    return set(done.stdout.splitlines()) if done.returncode == 0 else None


def pytest_sessionstart(session):
    session.config.stash[_TREE] = _untracked_files()


def pytest_sessionfinish(session, exitstatus):
    """The suite leaves no file behind in the working tree: tests write only under ``tmp_path``."""
    before, after = session.config.stash.get(_TREE, None), _untracked_files()
    if before is None or after is None or not after - before:
        return
    session.config.get_terminal_writer().line(
        "the tests left files in the working tree (tests must write only under tmp_path): "
        + ", ".join(sorted(after - before)), red=True)
    session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture(autouse=True)
def _work_in_tmp_path(tmp_path, monkeypatch):
    """Every test runs in its own empty folder, so that a relative path it writes lands under ``tmp_path``."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="session")
def stand():
    """The built-in ``drop-stand``."""
    return get_rig()


@pytest.fixture(scope="session")
def stiff_stand():
    """The earlier built-in stand, ``drop-stand-stiff`` (nearly elastic Kelvin-Voigt contact, 30 N friction)."""
    return get_rig("drop-stand-stiff")


@pytest.fixture(scope="session")
def free_bodies():
    """The stand reduced to two free bodies in a Kelvin-Voigt contact: no gravity, no friction, and a gas spring
    of 1 Pa in 1 m³ chambers (its stiffness, ~1e-5 N/m, is 11 orders of magnitude below the contact's)."""
    return get_rig("drop-stand-stiff").replace(**{
        "gravity": 0.0, "friction.force": 0.0, "gas.atmospheric_pressure": 1.0, "cylinder.dead_volume_lower": 1.0,
        "cylinder.dead_volume_upper": 1.0})
