"""Valve Z, its actuator, the one stepper, the controlled loop, the bound η_max and the metrics: physics limits and
invariants."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from impactometer.constants import STANDARD_GRAVITY
from impactometer.control import ControlSettings, plant
from impactometer.control import controller as ctl
from impactometer.control.bound import closed_curve, efficiency_bound
from impactometer.control.event import common_window
from impactometer.control.metrics import absorption_metrics
from impactometer.control.strategies import get_strategy, strategy_names
from impactometer.control.valve import Absorber, ValveDrive, effective_area, iso6358_valve, valve_mass_flow
from impactometer.errors import ParameterError
from impactometer.model import actuated, simulate, stepper
from impactometer.model import dynamics as d
from impactometer.model.forces import ISO_REFERENCE_DENSITY, ISO_REFERENCE_TEMPERATURE, LAMINAR_RATIO
from impactometer.model.setup import initial_state, pack
from impactometer.rig import Rig, Scenario, Valve, get_rig

SCENARIO = Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3)


def _control(strategy, **kw):
    p = pack(get_rig(), SCENARIO)
    y0 = initial_state(p)
    base = dict(strategy=strategy, start=0.02, mass=SCENARIO.mass, velocity=SCENARIO.velocity,
                usable_stroke=0.19, pressure_lower_start=float(y0[d.P_LOWER]), refine_mass=False)
    return ControlSettings(**{**base, **kw})


def test_closed_valve_rhs_is_the_model_rhs_exactly():
    rng = np.random.default_rng(1)
    for rig in (get_rig(), get_rig("drop-stand-pad")):
        p = pack(rig, SCENARIO)
        u = np.array([0.0, 1e-3, np.inf, actuated.TO_UPPER])
        for _ in range(50):
            y = initial_state(p) * (1.0 + 0.3 * rng.standard_normal(d.N_STATE))
            y[d.U1] = rng.uniform(0.0, 0.1)
            y[d.U2] = rng.uniform(0.0, 0.1)
            expected = np.empty(d.N_STATE)
            d.rhs(y, p, 0.0, expected)
            got = np.empty(actuated.N_STATE)
            actuated.derivatives(np.append(y, 0.0), p, u, got)
            assert np.array_equal(got[:d.N_STATE], expected)
            assert got[actuated.OPENING] == 0.0


def test_one_step_follows_the_dormand_prince_tableau():
    """The written-out stage sums of the shared step are the tableau's, for both systems."""
    rig = get_rig("drop-stand-pad")
    p = pack(rig, SCENARIO)
    for system, n in ((stepper.PLAIN, d.N_STATE), (stepper.ACTUATED, actuated.N_STATE)):
        y = np.append(initial_state(p), 0.3)[:n]
        y[d.U1], y[d.U2], y[d.V1] = 0.01, 0.008, 1.5
        u = np.array([0.8, 2e-3, np.inf, actuated.TO_UPPER])
        h, rtol = 2e-5, 1e-7
        atol = rtol * np.ones(n)
        k = np.empty((stepper.WORK_ROWS, n))
        stepper.evaluate(system, y, p, u, k[0])
        norm = stepper.attempt(system, y, h, k, p, u, rtol, atol)
        stages = np.empty((stepper.STAGES, n))
        stages[0] = k[0]
        for i in range(1, stepper.STAGES):
            stepper.evaluate(system, y + h * (stepper.COUPLING[i, :i] @ stages[:i]), p, u, stages[i])
        y_new = y + h * (stepper.COUPLING[6, :6] @ stages[:6])
        assert np.allclose(k[:stepper.STAGES], stages, rtol=1e-12, atol=1e-9 * np.abs(stages).max())
        assert np.allclose(k[stepper.NEW_STATE], y_new, rtol=1e-14, atol=1e-18)
        error = h * (stepper.ERROR_WEIGHTS @ stages) / (atol + rtol * np.maximum(np.abs(y), np.abs(y_new)))
        assert norm == pytest.approx(np.sqrt(np.mean(error ** 2)), rel=1e-6)
    assert np.allclose(stepper.COUPLING.sum(axis=1)[1:], stepper.NODES[1:])  # consistency of the tableau


def test_closed_loop_with_closed_valve_reproduces_the_reference_simulation():
    ref = simulate(SCENARIO, duration=0.06, sample_rate=20e3, integrator="reference")
    got, _ = plant.simulate_controlled(SCENARIO, duration=0.06, sample_rate=20e3, rtol=1e-10)
    # tolerance: 1e-6 of the stroke scale and of the peak force (rtol 1e-10 on both sides)
    assert np.max(np.abs(got.u1 - ref.u1)) < 1e-6 * 0.2
    assert np.max(np.abs(got.contact_force - ref.contact_force)) < 1e-4 * ref.contact_force.max()
    assert np.max(np.abs(got.pressure_lower - ref.pressure_lower)) < 1e-6 * ref.pressure_lower.max()


def test_an_opening_program_replaces_the_controller():
    """A program of zeros is the closed valve, sample for sample, whatever the controller would do; a constant
    program is the constant strategy's opening without its controller (no supervisor, no closing at the stop)."""
    closed, _ = plant.simulate_controlled(SCENARIO, duration=0.06, sample_rate=20e3)
    n = closed.time.size
    held, history = plant.simulate_controlled(SCENARIO, control=_control("predictive", start=0.0), duration=0.06,
                                             sample_rate=20e3, program=np.zeros(n))
    assert np.array_equal(held.u1, closed.u1) and np.array_equal(held.contact_force, closed.contact_force)
    assert np.all(history["valve_opening"] == 0.0)
    opened, history = plant.simulate_controlled(SCENARIO, duration=0.06, sample_rate=20e3, program=np.full(n, 0.5))
    # after the dead time the opening follows the first-order lag towards the command
    drive = ValveDrive()
    t = opened.time - drive.dead_time
    expected = np.where(t > 0.0, 0.5 * (1.0 - np.exp(-np.clip(t, 0.0, None) / drive.time_constant)), 0.0)
    assert np.max(np.abs(history["valve_opening"] - expected)) < 0.5 * 20e3 ** -1 / drive.time_constant
    with pytest.raises(ParameterError, match="program must hold"):
        plant.simulate_controlled(SCENARIO, duration=0.06, sample_rate=20e3, program=np.full(n, 1.5))


def test_flow_between_chambers_conserves_gas_mass_and_energy():
    result, history = plant.simulate_controlled(SCENARIO, control=_control("constant", opening=0.6),
                                               duration=0.08, sample_rate=20e3)
    assert history["valve_opening"].max() > 0.2  # the valve did open
    total = result.gas_mass_lower + result.gas_mass_upper
    assert np.max(np.abs(total - total[0])) < 1e-9 * total[0]
    # throttling keeps the energy in the gas: stored + dissipated is conserved (rtol 1e-7 integration)
    assert result.energy_balance_error < 1e-5


def test_venting_to_atmosphere_removes_gas_from_the_lower_chamber_only():
    drive = ValveDrive(route="atmosphere")
    result, _ = plant.simulate_controlled(SCENARIO, control=_control("constant", opening=0.6), drive=drive,
                                         duration=0.06, sample_rate=20e3)
    assert result.gas_mass_lower[-1] < 0.9 * result.gas_mass_lower[0]
    assert np.allclose(result.gas_mass_upper, result.gas_mass_upper[0], rtol=1e-12)


def test_choked_orifice_flow_matches_the_closed_form():
    rig = get_rig("drop-stand-stiff")  # the orifice valve
    gamma, r_gas, cd = rig.gas.gamma, rig.gas.gas_constant, rig.valve.discharge_coefficient
    p_up, temp, area = 500e3, 300.0, 2e-5
    expected = cd * area * p_up * math.sqrt(gamma / (r_gas * temp)) * (2 / (gamma + 1)) ** (
        (gamma + 1) / (2 * (gamma - 1)))
    assert valve_mass_flow(p_up, temp, 0.3 * p_up, area, rig=rig) == pytest.approx(expected, rel=1e-12)
    # continuous at the critical ratio and at the laminar transition, zero at equal pressures, monotone
    critical = (2 / (gamma + 1)) ** (gamma / (gamma - 1))
    for ratio in (critical, LAMINAR_RATIO):
        below, above = valve_mass_flow(p_up, temp, p_up * ratio * np.array([1 - 1e-10, 1 + 1e-10]), area, rig=rig)
        assert abs(below - above) < 1e-6 * expected
    flows = valve_mass_flow(p_up, temp, p_up * np.linspace(0.1, 1.0, 2001), area, rig=rig)
    assert flows[-1] == 0.0
    assert np.all(np.diff(flows) <= 1e-15)


def test_iso6358_flow_matches_the_standard_and_the_equivalent_orifice():
    rig = iso6358_valve(1e-4, rig="drop-stand-pad", critical_ratio=0.3)
    conductance, b = rig.valve.sonic_conductance, rig.valve.critical_ratio
    p_up, temp, full = 500e3, 320.0, rig.valve.max_area
    choked = conductance * p_up * ISO_REFERENCE_DENSITY * math.sqrt(ISO_REFERENCE_TEMPERATURE / temp)
    assert valve_mass_flow(p_up, temp, 0.2 * p_up, full, rig=rig) == pytest.approx(choked, rel=1e-12)
    ratio = 0.6
    subsonic = choked * math.sqrt(1.0 - ((ratio - b) / (1.0 - b)) ** 2)
    assert valve_mass_flow(p_up, temp, ratio * p_up, full, rig=rig) == pytest.approx(subsonic, rel=1e-12)
    # a partly open valve has the conductance scaled by the opening
    assert valve_mass_flow(p_up, temp, ratio * p_up, 0.25 * full, rig=rig) == pytest.approx(0.25 * subsonic,
                                                                                            rel=1e-12)
    # continuous at b and at the laminar transition, zero at equal pressures, monotone in the pressure ratio
    for r in (b, LAMINAR_RATIO):
        below, above = valve_mass_flow(p_up, temp, p_up * r * np.array([1 - 1e-10, 1 + 1e-10]), full, rig=rig)
        assert abs(below - above) < 1e-6 * choked
    flows = valve_mass_flow(p_up, temp, p_up * np.linspace(0.05, 1.0, 2001), full, rig=rig)
    assert flows[-1] == 0.0 and np.all(np.diff(flows) <= 1e-15)
    # its effective area is the orifice (C_d·A) that passes the same choked flow
    area = effective_area(rig)
    assert area == pytest.approx(1e-4, rel=1e-12)
    orifice = rig.replace(**{"valve.law": "orifice", "valve.discharge_coefficient": 0.5, "valve.max_area": 2e-4})
    assert valve_mass_flow(p_up, temp, 0.2 * p_up, 2e-4, rig=orifice) == pytest.approx(choked, rel=1e-9)


def test_actuator_dead_time_lag_and_rate_limit():
    tau, dead, fs, start = 2e-3, 0.73e-3, 50e3, 0.01
    control = _control("constant", opening=0.8, start=start, close_on_stop=False, supervise=False)
    _, history = plant.simulate_controlled(SCENARIO, control=control, drive=ValveDrive(time_constant=tau,
                                                                                      dead_time=dead),
                                          duration=0.025, sample_rate=fs)
    t = np.arange(history["valve_opening"].size) / fs
    # the command leaves at the first sample at or after the start, arrives a dead time later
    sent = t[np.searchsorted(t, start - 1e-12)]
    expected = np.where(t > sent + dead, 0.8 * (1.0 - np.exp(-(t - sent - dead) / tau)), 0.0)
    assert np.max(np.abs(history["valve_opening"] - expected)) < 1e-4
    assert np.all(history["valve_opening"][t <= sent + dead] == 0.0)
    rate = 1.0 / 5e-3  # the full stroke in 5 ms
    _, limited = plant.simulate_controlled(SCENARIO, control=control, duration=0.025, sample_rate=fs,
                                          drive=ValveDrive(time_constant=1e-5, max_rate=rate, dead_time=0.0))
    slope = np.diff(limited["valve_opening"]) * fs
    assert slope.max() <= rate * (1 + 1e-6)
    assert limited["valve_opening"][-1] == pytest.approx(0.8, rel=1e-6)
    assert np.all(limited["valve_opening"] >= 0.0) and np.all(limited["valve_opening"] <= 1.0)


def test_response_time_of_the_drive():
    assert ValveDrive(time_constant=1.4e-3).response_time == pytest.approx(1.4e-3 * math.log(9.0), rel=1e-12)
    # rate limited: 10 % to 90 % of the stroke at the largest rate
    assert ValveDrive(time_constant=1e-6, max_rate=200.0).response_time == pytest.approx(0.8 / 200.0, rel=1e-3)
    assert ValveDrive().response_time >= 3e-3  # the built-in valve is one that exists


@pytest.mark.parametrize("kwargs, match", [
    ({"time_constant": 0.0}, "time_constant"), ({"time_constant": math.nan}, "time_constant"),
    ({"dead_time": -1e-3}, "dead_time must be a finite number >= 0"), ({"dead_time": 1.0}, "dead_time"),
    ({"max_rate": -1.0}, "max_rate"), ({"route": "sideways"}, "route")])
def test_invalid_valve_drive(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        ValveDrive(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    ({"law": "iso6358", "sonic_conductance": -1e-7, "critical_ratio": 0.3}, r"valve.sonic_conductance must be > 0"),
    ({"law": "iso6358", "sonic_conductance": 1e-7, "critical_ratio": 1.2}, r"valve.critical_ratio must be"),
    ({"law": "iso6358", "sonic_conductance": 1e-7, "critical_ratio": 0.0}, r"valve.critical_ratio must be"),
    ({"law": "iso6358", "sonic_conductance": 1e-7, "critical_ratio": 1.0}, r"within \(0, 1\), got 1.0"),
    ({"law": "orifice", "sonic_conductance": 1e-7}, "not of the orifice law"),
    ({"law": "venturi"}, "valve.law must be one of")])
def test_invalid_valve(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        Valve(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    ({"strategy": "bang-bang"}, "control.strategy must be one of"), ({"opening": 1.5}, "control.opening"),
    ({"mass": -1.0}, "control.mass"), ({"start": math.nan}, "control.start"),
    ({"strategy": "level"}, "control.force_level"), ({"tau_control": 0.0}, "control.tau_control"),
    ({"refine_mass": 1}, "control.refine_mass must be True or False")])
def test_invalid_control_settings(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        ControlSettings(**kwargs)


def test_invalid_absorber_and_flow_inputs():
    with pytest.raises(ParameterError, match="stroke_margin"):
        Absorber(stroke_margin=-0.01)
    with pytest.raises(ParameterError, match="stroke_margin"):
        Absorber(stroke_margin=0.3).usable_stroke(get_rig())
    with pytest.raises(ParameterError, match="rated_force"):
        Absorber(rated_force=0.0)
    with pytest.raises(ParameterError, match="bounce_gate"):
        Absorber(bounce_gate=1)
    with pytest.raises(ParameterError, match="area"):
        valve_mass_flow(5e5, 300.0, 1e5, 1.0)
    with pytest.raises(ParameterError, match="pressure_up"):
        valve_mass_flow(-5e5, 300.0, 1e5, 1e-5)


def test_bounce_gate_holds_the_valve_closed_while_the_bodies_part():
    gated = _control("realtime", bounce_gate=True, bounce_threshold=0.05).packed()
    assert ctl.bounce_gate(gated, 0.6, 0.2) == 0.6  # approaching faster than the threshold: the law acts
    assert ctl.bounce_gate(gated, 0.6, 0.01) == 0.0
    assert ctl.bounce_gate(gated, 0.6, -0.5) == 0.0  # parting: closed
    assert ctl.bounce_gate(_control("realtime").packed(), 0.6, -0.5) == 0.6  # gate off: the law's command


def test_strategy_registry():
    assert strategy_names("all") == ["closed", "constant", "realtime", "predictive"]
    assert get_strategy("auto") is get_strategy("predictive")
    with pytest.raises(ParameterError, match=r"strategy must be one of \['auto', 'closed', 'constant', "):
        get_strategy("bang-bang")
    with pytest.raises(ParameterError, match="strategy"):
        strategy_names(["closed", "open"])


def test_bound_is_a_constant_force_when_the_closed_curve_is_already_above_the_level():
    closed = simulate(SCENARIO, duration=0.1, sample_rate=20e3)
    bound = efficiency_bound(closed, 0.02, 0.19)
    i0 = int(np.searchsorted(closed.time, 0.02))
    u0, v0 = closed.u1[i0], closed.v1[i0]
    g = closed.rig.gravity
    # a constant force over the rest of the stroke: F·S = M1·v²/2 + M1·g·S
    level = SCENARIO.mass * (v0 ** 2 / (2 * (0.19 - u0)) + g)
    assert bound.efficiency == pytest.approx(1.0, abs=1e-9)
    assert bound.level == pytest.approx(level, rel=2e-3)


def test_bound_follows_the_closed_curve_then_holds_and_stops_at_the_end_of_the_stroke():
    scenario = Scenario(mass=50.0, velocity=3.0, pressure_gauge=20e3)
    closed = simulate(scenario, duration=0.1, sample_rate=20e3)
    usable = 0.19
    bound = efficiency_bound(closed, 0.035, usable)
    assert 0.5 < bound.efficiency < 1.0
    i0 = int(np.searchsorted(closed.time, 0.035))
    s = np.linspace(closed.u1[i0], usable, 20001)
    curve = closed_curve(closed.rig, 50.0, s, piston_position=closed.u2[i0],
                         pressure_lower=closed.pressure_lower[i0], pressure_upper=closed.pressure_upper[i0])
    work = np.trapezoid(np.minimum(curve, bound.level), s)
    need = 0.5 * 50.0 * closed.v1[i0] ** 2 + 50.0 * closed.rig.gravity * (usable - closed.u1[i0])
    assert work == pytest.approx(need, rel=2e-3)
    assert curve[0] < bound.level < curve[-1]
    # a longer stroke lowers the level
    assert efficiency_bound(closed, 0.035, 0.195).level < bound.level


def _constant_deceleration_run(mass=20.0, v0=2.0, decel=15.0, fs=20e3, relative_velocity=0.0, stage_a=0.0):
    """A stage A of ``stage_a`` s (one collision pulse, then flight at V0), then a constant deceleration to rest."""
    t = np.arange(int(0.5 * fs)) / fs
    after = np.clip(t - stage_a, 0.0, None)
    t_stop = v0 / decel
    v = np.where(after < t_stop, v0 - decel * after, 0.0)
    u = v0 * np.minimum(t, stage_a) + np.where(after < t_stop, v0 * after - 0.5 * decel * after ** 2,
                                                 v0 ** 2 / (2 * decel))
    force = np.where(after < t_stop, mass * (STANDARD_GRAVITY + decel), mass * STANDARD_GRAVITY)
    if stage_a > 0.0:  # a 4 ms collision, then the bodies apart until stage B
        pulse = t < 4e-3
        force = np.where(pulse, 2e3 * np.sin(np.pi * t / 4e-3), np.where(t < stage_a, 0.0, force))
    return SimpleNamespace(time=t, contact_force=force, u1=u, v1=v, v2=v - relative_velocity,
                           bottom_stop_force=np.zeros_like(t),
                           scenario=Scenario(mass=mass, velocity=v0), rig=Rig(), extra={}), t_stop + stage_a


def _with_chambers(run, pressure=1.3e5):
    """The run with both chambers at ``pressure`` [Pa] and the piston following the mass (a closed-valve run as
    ``common_window`` reads it)."""
    out = SimpleNamespace(**vars(run))
    out.pressure_lower = np.full_like(run.time, pressure)
    out.pressure_upper = np.full_like(run.time, pressure)
    out.u2 = run.u1
    return out


def test_metrics_of_a_constant_deceleration_are_ideal():
    run, t_stop = _constant_deceleration_run()
    usable = 2.0 ** 2 / 30.0  # the deceleration uses exactly the usable stroke: F0 is its force
    m = absorption_metrics(run, 0.0, usable)
    assert m.impact_force == pytest.approx(20.0 * (STANDARD_GRAVITY + 15.0), rel=1e-12)
    # the CFC 60 filter rings by a few percent at the end of the deceleration (a 300 N step down)
    assert m.whole_event_peak_ratio == pytest.approx(1.0, abs=0.03)
    assert m.peak_deceleration_g == pytest.approx(15.0 / STANDARD_GRAVITY, rel=0.06)
    assert m.whole_event_efficiency == pytest.approx(1.0, abs=0.03)
    assert m.controlled_efficiency == pytest.approx(1.0, abs=1e-3)
    assert m.stopped and m.time_to_stop == pytest.approx(t_stop, abs=2 / 20e3)
    assert m.stroke_used == pytest.approx(usable, rel=1e-6) and m.stroke_utilisation == pytest.approx(1.0, rel=1e-6)
    assert m.max_deceleration == pytest.approx(15.0, rel=1e-9)
    assert not m.bottomed_out and not m.rebounded
    assert m.energy_absorbed == pytest.approx(0.5 * 20 * 4 + 20 * STANDARD_GRAVITY * 4 / 30, rel=1e-6)
    assert m.bounce_energy == 0.0  # sustained contact: no relative motion
    assert not m.own_window  # one contact pulse from the first contact on: no stage A, so no stage B either
    # without a common window R_B is undefined, the whole event is judged all the same
    assert math.isnan(m.stage_b_ratio) and m.to_dict()["stage_b_ratio"] is None


def test_a_mass_still_moving_at_the_end_of_its_record_has_not_stopped():
    run, _ = _constant_deceleration_run()
    cut = SimpleNamespace(**vars(run))
    for name in ("time", "contact_force", "u1", "v1", "v2", "bottom_stop_force"):
        setattr(cut, name, getattr(run, name)[:1000])  # 50 ms of a 133 ms deceleration
    m = absorption_metrics(cut, 0.0, 0.19)
    assert not m.stopped and math.isnan(m.time_to_stop)


def test_r_b_of_a_constant_deceleration_on_the_common_window_is_one():
    run, _ = _constant_deceleration_run(stage_a=0.05)  # the stage-A collision ends 46 ms before stage B
    usable = float(run.u1.max())
    window = common_window(_with_chambers(run), usable)
    assert window.start == pytest.approx(0.05, abs=2 / 20e3) and not window.reason
    # F_ref from the state at t_w: V0 with the stroke left after the flight of stage A
    remaining = usable - float(run.u1[np.searchsorted(run.time, window.start)])
    assert window.reference_force == pytest.approx(20.0 * (2.0 ** 2 / (2 * remaining) + STANDARD_GRAVITY), rel=1e-9)
    m = absorption_metrics(run, 0.06, usable, window)  # the control start does not move the window
    assert m.common_window_start == window.start and m.reference_force == window.reference_force
    # the phaseless CFC 60 filter overshoots the 500 N step of the landing by about 3.5 %
    assert m.stage_b_ratio == pytest.approx(1.0, abs=0.05)
    # stopping short of the usable stroke needs more than F_ref: R_B > 1 by the ratio of the two forces
    longer = common_window(_with_chambers(run), usable + 0.05)
    assert absorption_metrics(run, 0.06, usable, longer).stage_b_ratio == pytest.approx(
        20.0 * (STANDARD_GRAVITY + 15.0) / longer.reference_force, rel=0.05)


def test_the_floor_is_the_share_of_friction_and_rod_force_the_mass_carries():
    run, _ = _constant_deceleration_run(stage_a=0.05)
    rig = run.rig
    pressure = 1e6  # the merged chambers at 10 bar: the floor is far above F_ref
    window = common_window(_with_chambers(run, pressure), float(run.u1.max()))
    c = rig.cylinder
    floor = 20.0 * (rig.friction.force + (pressure - rig.gas.atmospheric_pressure) * c.rod_area) / (
        20.0 + c.piston_mass)
    assert window.floor_force == pytest.approx(floor, rel=1e-9) and floor > window.reference_force
    m = absorption_metrics(run, 0.0, float(run.u1.max()), window)
    assert m.stage_b_ratio == pytest.approx(m.stage_b_peak_force / floor, rel=1e-12)
    vented = common_window(_with_chambers(run, pressure), float(run.u1.max()), vented=True)
    assert vented.floor_force == pytest.approx(20.0 * rig.friction.force / (20.0 + c.piston_mass), rel=1e-12)


def test_the_common_window_is_never_restarted():
    """A parting of the bodies after the first sustained contact neither moves the window nor drops the force
    before it; the window of one impact is the same for a run whose own stage B starts later."""
    run, _ = _constant_deceleration_run(stage_a=0.05)
    usable = float(run.u1.max())
    window = common_window(_with_chambers(run), usable)
    parted = SimpleNamespace(**vars(run))
    force = run.contact_force.copy()
    force[(run.time > 0.06) & (run.time < 0.065)] += 400.0  # a collision ...
    force[(run.time >= 0.065) & (run.time < 0.066)] = 0.0  # ... and the bodies apart for 1 ms
    parted.contact_force = force
    m = absorption_metrics(parted, 0.0, usable, window)
    assert m.common_window_start == window.start
    assert m.own_window_start > 0.065  # the earlier metric restarted its window at the new contact
    assert m.stage_b_ratio > 1.3 > m.own_window_force_ratio


def test_the_wide_window_counts_a_peak_moved_before_the_common_window():
    """R_B,wide starts 1 ms after the first contact pulse of the closed-valve run: a run whose peak comes between
    then and t_w (a collision moved ahead of the window) scores it there, while R_B does not see it; without such a
    peak the two agree."""
    from impactometer.control.event import WIDE_DELAY

    run, _ = _constant_deceleration_run(stage_a=0.05)
    usable = float(run.u1.max())
    window = common_window(_with_chambers(run), usable)
    assert window.wide_start == pytest.approx(4e-3 + WIDE_DELAY, abs=2 / 20e3)  # the 4 ms collision's end + 1 ms
    plain = absorption_metrics(run, 0.0, usable, window)
    assert plain.wide_window_ratio == pytest.approx(plain.stage_b_ratio, rel=1e-9)
    assert plain.to_dict()["wide_window_start_s"] == window.wide_start
    moved = SimpleNamespace(**vars(run))
    force = run.contact_force.copy()
    force[(run.time > 0.03) & (run.time < 0.035)] = 1500.0  # a collision before t_w = 50 ms
    moved.contact_force = force
    m = absorption_metrics(moved, 0.0, usable, window)
    assert m.stage_b_ratio == pytest.approx(plain.stage_b_ratio, rel=1e-3)  # the phaseless filter leaks a trace
    assert m.wide_window_ratio > 2.0 * m.stage_b_ratio
    assert m.wide_window_peak_force == pytest.approx(m.wide_window_ratio * window.denominator, rel=1e-12)


def test_a_mass_stopped_in_stage_a_has_no_common_window():
    run, _ = _constant_deceleration_run(stage_a=0.01)
    stopped = SimpleNamespace(**vars(_with_chambers(run)))
    stopped.u1 = np.where(run.time < 2e-3, run.time * 2.0, 4e-3 - (run.time - 2e-3) * 0.1)  # deepest at 2 ms
    window = common_window(stopped, 0.19)
    assert math.isnan(window.start) and "stage A" in window.reason
    m = absorption_metrics(stopped, 0.005, 0.19, window)
    assert not m.own_window and math.isnan(m.stage_b_ratio) and math.isnan(m.own_window_start)
    assert m.to_dict()["stage_b_ratio"] is None and m.to_dict()["wide_window_ratio"] is None


def test_bounce_energy_is_the_kinetic_energy_of_the_relative_motion():
    run, _ = _constant_deceleration_run(relative_velocity=1.5)
    reduced = 20.0 * run.rig.cylinder.piston_mass / (20.0 + run.rig.cylinder.piston_mass)
    assert absorption_metrics(run, 0.0, 0.19).bounce_energy == pytest.approx(0.5 * reduced * 1.5 ** 2, rel=1e-12)


def test_closed_capacity_is_the_work_of_the_adiabatic_gas_spring():
    rig = get_rig()
    p = pack(rig, SCENARIO)
    u0, travel, p_lower, p_upper = 0.05, 0.12, 4.2e5, 0.9e5
    c, gamma = rig.cylinder, rig.gas.gamma
    s = np.linspace(u0, u0 + travel, 200001)
    lower0, upper0 = d.volumes(u0, p)
    lower = c.area * (c.lower_length - s) + c.dead_volume_lower
    upper = c.annulus_area * (c.upper_length + s) + c.dead_volume_upper
    force = (p_lower * (lower0 / lower) ** gamma * c.area - p_upper * (upper0 / upper) ** gamma * c.annulus_area
             - rig.gas.atmospheric_pressure * c.rod_area + rig.friction.force)
    assert ctl.closed_capacity(p, p_lower, p_upper, u0, travel) == pytest.approx(np.trapezoid(force, s), rel=1e-8)


@pytest.mark.parametrize("strategy", ["realtime", "predictive"])
@pytest.mark.parametrize("rig", ["drop-stand", "drop-stand-stiff"])
def test_controller_keeps_enough_gas_to_stop_a_heavy_fast_impact_at_low_pressure(strategy, rig):
    scenario = Scenario(mass=50.0, velocity=3.0, pressure_gauge=20e3)
    p = pack(get_rig(rig), scenario)
    control = ControlSettings(strategy=strategy, start=0.02, mass=50.0, mass_std=0.0, velocity=3.0,
                              usable_stroke=0.19, pressure_lower_start=float(initial_state(p)[d.P_LOWER]),
                              refine_mass=False, tau_control=5e-3)
    result, _ = plant.simulate_controlled(scenario, rig, control=control, duration=0.4, sample_rate=50e3)
    assert result.bottom_stop_force.max() == 0.0 and "ended_at_bottom" not in result.extra
    # the piston stays within the usable stroke (the mass goes deeper by the contact's compression)
    assert result.u2.max() < 0.19 + 0.002


@settings(max_examples=60, deadline=None)
@given(p_up=st.floats(1.2e5, 2e6), ratio=st.floats(0.0, 1.5), temperature=st.floats(200.0, 600.0),
       area=st.floats(0.0, 5e-5))
def test_valve_flow_properties(p_up, ratio, temperature, area):
    flow = valve_mass_flow(p_up, temperature, max(ratio * p_up, 1.0), area)
    assert flow >= 0.0
    if ratio >= 1.0 or area == 0.0:
        assert flow == 0.0
    # linear in the opening, and more flow for a higher upstream pressure at the same downstream pressure
    assert valve_mass_flow(p_up, temperature, max(ratio * p_up, 1.0), area / 2) == pytest.approx(flow / 2, rel=1e-12,
                                                                                                abs=1e-18)
    assert valve_mass_flow(1.1 * p_up, temperature, max(ratio * p_up, 1.0), area) >= flow


def test_an_iso6358_valve_takes_the_built_in_valves_parameters_it_leaves_out():
    valve = Valve(critical_ratio=0.4)
    assert (valve.law, valve.sonic_conductance, valve.critical_ratio) == ("iso6358", 2e-7, 0.4)
    assert Valve(law="orifice").sonic_conductance is None
