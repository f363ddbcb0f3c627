"""Shared fixtures: the built-in stand and a stand reduced to two free bodies."""

from __future__ import annotations

import matplotlib
import pytest

from impactometer.rig import get_rig

matplotlib.use("Agg")


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
