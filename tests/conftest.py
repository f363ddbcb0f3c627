"""Shared fixtures: the built-in stand and a stand reduced to two free bodies; the hypothesis profiles."""

from __future__ import annotations

import os

import matplotlib
import pytest
from hypothesis import settings

from impactometer.rig import get_rig

matplotlib.use("Agg")
# property tests draw the same examples on every run (CI); HYPOTHESIS_PROFILE=explore draws new ones
settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

# "ci" (the default): the same examples on every run, so a property test cannot fail on one run and pass on the next;
# "dev" (HYPOTHESIS_PROFILE=dev): hypothesis' own defaults, fresh random examples each run
settings.register_profile("ci", derandomize=True, deadline=None, print_blob=True)
settings.register_profile("dev")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


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
