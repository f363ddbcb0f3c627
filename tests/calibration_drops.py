"""Calibration sets of a stand unlike every preset, made with the reference integrator (shared by the calibration
tests): :mod:`impactometer.calibrate.synthetic`'s example stand under the names the tests use."""

from __future__ import annotations

from impactometer.calibrate import synthetic

TRUE_STAND = synthetic.EXAMPLE_STAND
BASE_STAND = synthetic.EXAMPLE_BASE
TRUTH = synthetic.EXAMPLE_TRUTH
CALIBRATION = synthetic.EXAMPLE_DROPS
HELD_BACK = synthetic.EXAMPLE_HELD_BACK
drops = synthetic.example_set
