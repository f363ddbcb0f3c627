"""The model fit with valve Z's opening as an input: a record with a ``valve_opening`` channel is predicted with
that opening (the stand's own flow law at the area opening · A_max), so that an open valve does not corrupt the
identification; without the channel, or with it zero throughout, the fit is the closed-valve one, bit for bit.

Tolerances are stated in standard errors (``Z`` = 4 stated σ: a Gaussian estimate fails by chance with probability
6e-5) and, for the piecewise integration, in the integrator's own tolerance.
"""

import dataclasses

import numpy as np
import pytest

from impactometer.errors import ParameterError
from impactometer.identify.model_fit import forward as fw
from impactometer.identify.model_fit import identify
from impactometer.model.setup import pack
from impactometer.rig import Scenario, get_rig
from impactometer.sensors import record

Z = 4.0
OPENING = 0.3
SCENARIO = Scenario(mass=30.0, velocity=2.0, pressure_gauge=100e3)
RECORD = {"sample_rate": 50e3, "duration": 0.05, "noise": 0.05, "pre_trigger": 0.02, "seed": 11}


def _open_rig(opening):
    rig = get_rig()
    return dataclasses.replace(rig, valve=dataclasses.replace(rig.valve, area=opening * rig.valve.max_area))


def _with_opening(rec, opening):
    return dataclasses.replace(rec, channels={**rec.channels, "valve_opening": np.asarray(opening, float)})


def test_an_open_valve_given_as_input_is_identified_and_without_it_is_not():
    rec = record(SCENARIO, _open_rig(OPENING), **RECORD)  # the valve open from before first contact
    given = identify(_with_opening(rec, np.where(rec.time >= -1e-3, OPENING, 0.0)), rig=get_rig())
    assert given.method == "model/ml" and given.details["path"] == "ml"
    assert abs(given.mass - SCENARIO.mass) <= Z * given.mass_std
    assert abs(given.velocity - SCENARIO.velocity) <= Z * given.velocity_std
    blind = identify(rec, rig=get_rig())  # the closed-valve model does not describe the record
    assert blind.details["path"] == "fallback" and blind.mass_std > 2.0 * given.mass_std


def test_a_valve_closed_throughout_is_the_closed_valve_fit_bit_for_bit():
    rec = record(SCENARIO, get_rig(), **RECORD)
    assert fw._valve_schedule(np.zeros(rec.time.size), rec.start_time, rec.sample_rate) is None
    plain = identify(rec)
    zero = identify(_with_opening(rec, np.zeros(rec.time.size)))
    assert (zero.mass, zero.velocity, zero.mass_std, zero.velocity_std) == \
        (plain.mass, plain.velocity, plain.mass_std, plain.velocity_std)


def test_the_schedule_holds_each_opening_from_its_sample():
    times, values = fw._valve_schedule([0.0, 0.0, 0.5, 0.5, 1.0, 0.0], -1e-3, 1e3)
    assert np.allclose(times, [1e-3, 3e-3, 4e-3]) and np.array_equal(values, [0.5, 1.0, 0.0])
    with pytest.raises(ParameterError, match="valve opening"):
        fw._valve_schedule([0.0, 1.5], 0.0, 1e3)


def test_a_piecewise_integration_agrees_with_one_piece():
    """A change of the schedule that keeps the opening restarts the integration there: the same history within
    the integrator's tolerance; an opening of the valve at 5 ms changes it from then on only."""
    rig = get_rig()
    p = pack(_open_rig(OPENING), SCENARIO)[None, :]
    grid = fw._make_grid(-2e-3, 50e3, 1000, "causal")
    whole = fw._predict(dataclasses.replace(grid, valve=(np.array([-1e-3]), np.array([OPENING]))), p, np.zeros(1))
    pieces = fw._predict(dataclasses.replace(grid, valve=(np.array([-1e-3, 5e-3]), np.array([OPENING, OPENING]))),
                         p, np.zeros(1))
    constant = fw._predict(grid, p, np.zeros(1))  # the parameters' own constant opening
    scale = np.max(np.abs(constant), axis=-1, keepdims=True)
    assert np.max(np.abs(whole - constant) / scale) < 1e-9
    assert np.max(np.abs(pieces - whole) / scale) < 1e3 * fw.FIT_RTOL
    closed = pack(rig, SCENARIO)[None, :]
    late = fw._predict(dataclasses.replace(grid, valve=(np.array([5e-3]), np.array([1.0]))), closed, np.zeros(1))
    shut = fw._predict(grid, closed, np.zeros(1))
    t = grid.start_time + np.arange(grid.size) / grid.sample_rate
    assert np.array_equal(late[..., t < 5e-3 - 2e-4], shut[..., t < 5e-3 - 2e-4])  # the causal filter's reach
    assert np.max(np.abs(late - shut)[..., t > 10e-3]) > 0.01 * np.max(np.abs(shut))


def test_one_predictor_with_or_without_a_schedule():
    """The one compiled predictor: an empty schedule is the one-piece integration from the state at contact, bit
    for bit; with a schedule the same rows on the calling thread and on the thread pool, and the same range
    check."""
    from impactometer.model import dynamics as d
    from impactometer.model import fast
    from impactometer.model.setup import contact_state
    from impactometer.model.simulate import MAX_STEP, absolute_tolerance

    p = pack(get_rig(), SCENARIO)
    grid = fw._make_grid(-2e-3, 50e3, 400, "causal")
    shift = 2e-3  # contact 2 ms after the first sample
    args = (fw.CHANNEL_INDEX, fw.FIT_RTOL, absolute_tolerance(fw.FIT_RTOL), MAX_STEP, fw.MAX_FIT_STEPS)
    out = np.full((2, grid.instants.size), np.nan)
    assert fw._predict_row(p, np.empty(d.N_STATE), grid.instants, shift, np.empty(0), np.empty(0), *args,
                           out) == fast.OK
    y0, t = np.empty(d.N_STATE), grid.instants - shift
    assert contact_state(p, y0)
    first = np.searchsorted(t, 0.0, side="right") - 1
    straight = np.zeros_like(out)
    assert fast.integrate_one(p, y0, t[first:], *args, straight[:, first:])[0] == fast.OK
    assert np.array_equal(out, straight)
    opened = dataclasses.replace(grid, valve=(np.array([-1e-3, 1e-3]), np.array([OPENING, 1.0])))
    rows = np.stack([p, pack(get_rig(), dataclasses.replace(SCENARIO, mass=20.0))])
    times = np.array([0.0, 1e-4])
    pool = fw._predict(opened, rows, times)
    assert np.array_equal(fw._predict(opened, rows, times, in_turn=True), pool)
    assert not np.array_equal(pool, fw._predict(grid, rows, times))
    far = rows.copy()
    far[1, d.MASS] = 1e9
    for in_turn in (True, False):
        with pytest.raises(fw.IdentificationError, match="outside"):
            fw._predict(opened, far, times, in_turn=in_turn)


def test_the_fits_horizon_follows_the_records_opening():
    """The span a fit reads ends before the piston's return onto its top stop, which the model predicts with the
    record's opening: closed, the piston returns within 200 ms of a 30 kg, 2 m/s drop on 100 kPa; with the valve
    open from before contact the charge vents and it does not, so the whole record is read."""
    layout = fw.make_layout(get_rig(), "hysteretic", (), pressure_gauge=SCENARIO.pressure_gauge, contact_time=0.0,
                            sample_rate=RECORD["sample_rate"])
    x = layout.variables({"mass": SCENARIO.mass, "velocity": SCENARIO.velocity, "contact_time": 0.0})
    grid = fw._make_grid(-2e-3, RECORD["sample_rate"], 100, "causal")
    closed, why = fw._horizon(layout, x, 0.2, grid)
    assert closed < 0.2 and "top stop" in why and (closed, why) == fw._horizon(layout, x, 0.2)
    opened = dataclasses.replace(grid, valve=(np.array([-1e-3]), np.array([1.0])))
    assert fw._horizon(layout, x, 0.2, opened) == (0.2, "the whole record")
