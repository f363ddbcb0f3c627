"""The fast (compiled, batch) integrator against scipy: the same algorithm, the same answers, clean failures."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import RK45, solve_ivp

from impactometer.errors import ParameterError, SimulationError
from impactometer.model import dynamics as d
from impactometer.model import fast, simulate, simulate_batch
from impactometer.model.reference import agreement, pulse_peaks
from impactometer.model.setup import initial_state, pack
from impactometer.model.simulate import absolute_tolerance, compare_integrators
from impactometer.rig import Scenario, get_rig

GRID = np.meshgrid([10.0, 20.0, 30.0, 40.0, 50.0], [1.0, 1.5, 2.0, 2.5, 3.0],
                   [20e3, 115e3, 210e3, 305e3, 400e3], indexing="ij")


@pytest.mark.slow
@pytest.mark.parametrize("name, law, pulses, rtol", [
    ("drop-stand", "kelvin-voigt", 3, None), ("drop-stand", "hunt-crossley", 3, None),
    pytest.param("drop-stand-pad", "hysteretic", 2, None, marks=pytest.mark.xfail(
        strict=True, reason="known miss at the default rtol 1e-9: the maxima of the pad's sustained contact are so "
        "flat (curvature about 1.6e-5 of the force per 5 µs sample squared) that their times differ by up to 2.3 µs "
        "while peak force and impulse agree to 1e-6")),
    ("drop-stand-pad", "hysteretic", 2, 1e-10),
    ("drop-stand-stiff", "kelvin-voigt", 3, None)])
def test_fast_agrees_with_reference_on_the_paper_grid(name, law, pulses, rtol):
    """125 scenarios (M1 10-50 kg, V0 1-3 m/s, p0 20-400 kPa), 50 ms at 200 kHz: peak contact force and impulse
    ∫Fc dt within 1e-4 relative, every contact-pulse peak time within 1 µs (fast: default rtol 1e-9 unless
    ``rtol`` says otherwise, reference: DOP853 rtol 1e-10). The hysteretic pad stand has fewer pulses (a rebound or
    two, then sustained contact); the peak times of its flat sustained-contact maxima converge with the fast
    integrator's tolerance (2.3 µs at 1e-9, 0.46 µs at 1e-10, 0.16 µs at 1e-11), so it is compared at 1e-10."""
    result = compare_integrators(*GRID, get_rig(name, contact=law), duration=0.05, sample_rate=200e3, rtol=rtol)
    assert result.scenarios == 125
    assert result.pulse_count_mismatches == 0
    assert result.pulses >= pulses * 125  # several pulses per record were compared
    assert result.peak_force < 1e-4
    assert result.impulse < 1e-4
    assert result.peak_time < 1e-6


def test_fast_kernel_is_scipy_rk45_step_for_step(free_bodies):
    """On a smooth problem (first contact of two free bodies) the kernel takes the steps of solve_ivp's RK45
    with the same tolerances, so both give the same numbers to round-off."""
    p = pack(free_bodies.replace(**{"contact.damping": 300.0}), Scenario(mass=30.0, velocity=2.0,
                                                                       pressure_gauge=0.0))
    y0 = initial_state(p)
    t = np.linspace(0.0, 3e-3, 31)
    for rtol in (1e-6, 1e-9):
        atol = absolute_tolerance(rtol)

        def fun(_t, y):
            dy = np.empty_like(y)
            d.rhs(y, p, 0.0, dy)
            return dy

        sol = solve_ivp(fun, (0.0, t[-1]), y0, method="RK45", t_eval=t, rtol=rtol, atol=atol)
        stepper, scipy_steps = RK45(fun, 0.0, y0, t[-1], rtol=rtol, atol=atol), 0
        while stepper.status == "running":
            stepper.step()
            scipy_steps += 1
        out = np.empty((d.N_STATE, t.size))
        status, steps = fast.integrate_one(p, y0, t, np.arange(d.N_STATE), rtol, atol, np.inf, 10**6, out)
        assert status == fast.OK
        assert steps == scipy_steps > 5
        scale = np.array([1e-3, 1.0, 1e-3, 1.0])  # [m, m/s, m, m/s]
        assert np.all(np.abs(out[:4] - sol.y[:4]).max(axis=1) < 1e-12 * scale)


def test_simulate_batch_matches_simulate(stand):
    """A batch row is the single-scenario simulation (same kernel), with stand overrides applied per row."""
    mass, velocity, pressure = [10.0, 50.0], [3.0, 1.0], [400e3, 20e3]
    stiffness = [1e6, 3e6]
    batch = simulate_batch(mass, velocity, pressure, stand, overrides={"contact.stiffness": stiffness},
                           channels=("contact_force", "a2", "u2"))
    for i in range(2):
        one = simulate(Scenario(mass=mass[i], velocity=velocity[i], pressure_gauge=pressure[i]),
                       stand.replace(**{"contact.stiffness": stiffness[i]}))
        np.testing.assert_array_equal(batch.time, one.time)
        for name in ("contact_force", "a2", "u2"):
            np.testing.assert_allclose(batch[name][i], getattr(one, name), rtol=0, atol=1e-9 * np.abs(
                getattr(one, name)).max())
    assert len(batch) == 2 and batch.steps.min() > 10


def test_float32_batch_is_the_rounded_float64_batch(stand):
    wide = simulate_batch(30.0, 2.0, 200e3, stand)
    narrow = simulate_batch(30.0, 2.0, 200e3, stand, dtype=np.float32)
    assert narrow["contact_force"].dtype == np.float32
    np.testing.assert_array_equal(narrow["contact_force"], wide["contact_force"].astype(np.float32))


@pytest.mark.parametrize("integrator", ["fast", "reference"])
def test_solver_failure_is_a_simulation_error(stand, integrator):
    with pytest.raises(SimulationError, match="steps"):
        simulate(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), stand, integrator=integrator,
                 max_steps=20)


def test_batch_failure_is_a_simulation_error_with_the_scenario(stand):
    with pytest.raises(SimulationError, match=r"2 scenario\(s\), first: mass=10.0"):
        simulate_batch([10.0, 20.0], 2.0, 200e3, stand, max_steps=20)


@pytest.mark.parametrize("kwargs, match", [
    ({"integrator": "euler"}, "integrator must be one of"),
    ({"rtol": 0.1}, "rtol must be <= 0.001"),
    ({"rtol": float("nan")}, "rtol must be a finite number"),
    ({"duration": 0.0}, "duration must be"),
    ({"duration": "50ms"}, "duration must be"),
    ({"sample_rate": -1.0}, "sample_rate must be"),
    ({"max_step": 0.0}, "max_step must be > 0"),
    ({"max_steps": 0}, "max_steps must be an integer"),
])
def test_bad_simulation_options(stand, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        simulate(Scenario(mass=30.0, velocity=2.0), stand, **kwargs)


@pytest.mark.parametrize("args, kwargs, match", [
    (([30.0, -1.0], 2.0, 200e3), {}, r"mass\[1\] must be a finite number > 0"),
    ((30.0, [2.0, np.nan], 200e3), {}, r"velocity\[1\] must be a finite number > 0"),
    ((30.0, 2.0, [-5.0]), {}, r"pressure_gauge\[0\] must be a finite number >= 0"),
    ((30.0, 2.0, [100e3, 500e3]), {}, r"pressure_gauge\[1\] must be <= the rated 400000"),
    (([1.0, 2.0], [1.0, 2.0, 3.0], 0.0), {}, "must broadcast together"),
    ((30.0, 2.0, 200e3), {"overrides": {"contact.stifness": 1e6}}, "unknown stand parameter 'contact.stifness'"),
    ((30.0, 2.0, 200e3), {"overrides": {"cylinder.rod_diameter": 0.09}}, "rod_diameter must be < bore"),
    ((30.0, 2.0, 200e3), {"channels": ("force",)}, "channels must be a non-empty subset"),
    ((30.0, 2.0, 200e3), {"channels": ()}, "channels must be a non-empty subset"),
])
def test_bad_batch_input(stand, args, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        simulate_batch(*args, stand, **kwargs)


def test_too_low_pressure_for_the_piston_is_a_parameter_error(stand):
    """A 400 kg piston on a 50 mm stroke would sink onto the bottom stop at p0 = 0."""
    heavy = stand.replace(**{"cylinder.piston_mass": 400.0, "cylinder.stroke": 0.05})
    with pytest.raises(ParameterError, match="too low to carry the piston"):
        simulate(Scenario(mass=30.0, velocity=2.0, pressure_gauge=0.0), heavy)


def test_pulse_peaks_are_refined_between_samples():
    """A sampled half-sine pulse: the parabola through the top three samples finds its peak to 1e-3 of a sample."""
    time = np.arange(0.0, 0.01, 1e-5)
    true_peak = 4.0031e-3
    force = np.where(np.abs(time - true_peak) < 2e-3, np.cos(np.pi * (time - true_peak) / 4e-3), 0.0)
    peaks, values = pulse_peaks(time, force)
    assert peaks.size == 1 and abs(peaks[0] - true_peak) < 1e-8
    assert values[0] == force.max()


def test_agreement_measures_a_shift():
    time = np.arange(0.0, 0.01, 1e-5)
    pulse = lambda t0: np.clip(np.cos(np.pi * (time - t0) / 2e-3), 0.0, None) * (np.abs(time - t0) < 1e-3)  # noqa: E731
    result = agreement(pulse(3e-3)[None, :], pulse(3.0005e-3)[None, :], time)
    assert result.pulses == 1 and result.peak_time == pytest.approx(5e-7, rel=1e-3)
    assert result.peak_force < 1e-3 and result.impulse < 1e-3


def test_single_channel_by_name(stand):
    batch = simulate_batch([10.0, 20.0], 2.0, 200e3, stand, channels="contact_force", duration=0.01)
    assert list(batch.data) == ["contact_force"] and batch["contact_force"].shape == (2, 501)


def test_helper_input_is_checked():
    from impactometer.model.setup import initial_states

    with pytest.raises(ParameterError, match="time and force must be 1-D arrays of equal length"):
        pulse_peaks(np.arange(5.0), np.zeros(4))
    with pytest.raises(ParameterError, match=rf"params must have shape \(n, {d.N_PARAM}\)"):
        initial_states(np.zeros((2, 3)))
    with pytest.raises(ParameterError, match="force histories must have equal shapes"):
        agreement(np.zeros((2, 5)), np.zeros((3, 5)), np.arange(5.0))
