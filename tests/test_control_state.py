"""The named layouts of the compiled control loop's vectors (:mod:`impactometer.control.state`)."""

import math
from dataclasses import fields

import numpy as np

from impactometer.control import ControlSettings, windows
from impactometer.control import estimator as est
from impactometer.control.state import (
    END_SLOTS,
    MAX_ENDS,
    N_ESTIMATOR,
    N_SUMS,
    N_WINDOWS,
    RING,
    Drive,
    End,
    Estimator,
    Settings,
    Strategy,
    Sums,
    Windows,
    pack_drive,
    pack_settings,
    unpack,
)
from impactometer.control.valve import ValveDrive
from impactometer.model.setup import initial_state, pack
from impactometer.rig import Scenario, get_rig


def test_settings_slots_are_the_dataclass_fields_in_order():
    assert [name.lower() for name in Settings._fields] == [f.name for f in fields(ControlSettings)]
    assert list(Settings) == list(range(len(Settings)))


def test_packing_and_unpacking_the_settings_round_trip():
    settings = ControlSettings(strategy="level", start=0.01, mass=20.0, force_level=1500.0, supervise=False)
    packed = pack_settings(settings)
    assert np.array_equal(packed, settings.packed(), equal_nan=True)
    named = unpack(Settings, packed)
    assert named["strategy"] == Strategy.LEVEL and named["force_level"] == 1500.0 and named["supervise"] == 0.0
    for f in fields(settings):
        if f.name != "strategy":
            assert named[f.name] == float(getattr(settings, f.name)) or math.isnan(named[f.name])


def test_drive_vector():
    drive = ValveDrive(dead_time=2e-3, time_constant=3e-3, max_rate=100.0)
    named = unpack(Drive, pack_drive(drive))
    assert named == {"dead_time": 2e-3, "time_constant": 3e-3, "max_rate": 100.0, "route": named["route"]}


def test_regions_of_the_windows_state_do_not_overlap():
    scalars = [slot for slot in Windows if slot < Windows.RUNNING]
    assert max(scalars) + 1 == Windows.RUNNING
    assert Windows.FORCE_RING == Windows.RUNNING + N_SUMS == Windows.RUNNING + len(Sums)
    assert Windows.SUMS_RING == Windows.FORCE_RING + RING
    assert Windows.ENDS == Windows.SUMS_RING + RING * N_SUMS
    assert N_WINDOWS == Windows.ENDS + MAX_ENDS * END_SLOTS and max(End) == END_SLOTS - 1
    assert N_ESTIMATOR == Estimator.WINDOWS + N_WINDOWS and max(Estimator) == Estimator.WINDOWS


def test_compiled_kernels_read_the_layouts_as_the_interpreted_code_does():
    """The kernels index their state with the layouts' slots: compiled (numba reads a slot as an integer constant)
    and interpreted they give the same state, bit for bit."""
    rig = get_rig("drop-stand-pad")
    y0 = initial_state(pack(rig, Scenario(mass=30.0, velocity=2.0, pressure_gauge=210e3)))
    ctrl = ControlSettings(strategy="predictive", start=0.0, mass=30.0, mass_std=1.0, force_noise=20.0,
                           acceleration_noise=1.0).packed()
    rng = np.random.default_rng(0)
    t = np.arange(3000) * 2e-5
    force = np.where(t > 1e-3, 4000.0 * np.abs(np.sin(2 * np.pi * 90.0 * (t - 1e-3))) + 3000.0, 0.0)
    force += 20.0 * rng.standard_normal(t.size)
    acceleration = -force / 30.0 + 9.81 + rng.standard_normal(t.size)
    states = []
    for initial, update in ((est.initial, est.update), (est.initial.py_func, est.update.py_func)):
        e = initial(y0, ctrl)
        for k in range(t.size):
            update(e, t[k], 2e-5, force[k], acceleration[k], 2e5, 1e5, 0.0, 9.81, ctrl)
        states.append(e)
    compiled, interpreted = states
    assert np.array_equal(compiled, interpreted, equal_nan=True)
    assert compiled[Estimator.WINDOWS + Windows.N_ENDS] > 2 and np.isfinite(compiled[Estimator.MASS])
    assert np.array_equal(windows.initial(), windows.initial.py_func(), equal_nan=True)
    pushed = []
    for push in (windows.push, windows.push.py_func):
        w = windows.initial()
        closed = [push(w, t[k], force[k], 9.81 - acceleration[k], 100.0, force[k] > 100.0, t[k] > 0.01, 20.0, 1.0)
                  for k in range(t.size)]
        pushed.append((w, closed))
    assert np.array_equal(pushed[0][0], pushed[1][0], equal_nan=True) and pushed[0][1] == pushed[1][1]
