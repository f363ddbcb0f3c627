"""The model's streaming identification: a first answer from the first milliseconds, updates at the stated cadence
within their stated σ, and a final answer equal to the batch fit of the same samples."""

import json

import numpy as np
import pytest

from impactometer.cli import main
from impactometer.errors import IdentificationError, ParameterError, ParameterTypeError, StreamFinishedError
from impactometer.identify.details import ModelDetails
from impactometer.identify.model_fit import cramer_rao, identify
from impactometer.identify.model_fit.select import STAGES
from impactometer.identify.model_fit.streaming import ModelStream, check_schedule
from impactometer.identify.peak_to_peak.streaming import StreamingIdentifier
from impactometer.io import write_recording
from impactometer.recording import Recording
from impactometer.rig import Scenario, get_rig
from impactometer.sensors import record

#: errors within this many stated σ (a test that fails once in ~16 000 draws for a Gaussian σ)
Z = 4.0
RECORD = {"sample_rate": 50e3, "duration": 0.04, "noise": 0.05, "pre_trigger": 0.02}


def _record(mass, velocity, pressure, seed, rig=None, **options):
    return record(Scenario(mass=mass, velocity=velocity, pressure_gauge=pressure), rig, seed=seed,
                  **{**RECORD, **options})


def _stream(rec, chunk=64, **options):
    stream = ModelStream(rec.sample_rate, start_time=rec.start_time, metadata=rec.metadata, **options)
    got = []
    for k in range(0, rec.contact_force.size, chunk):
        got += stream.push(rec.contact_force[k:k + chunk], rec.piston_acceleration[k:k + chunk])
    return stream, got


@pytest.mark.parametrize(("mass", "velocity", "pressure", "seed"), [(30.0, 2.0, 100e3, 11), (15.0, 2.5, 300e3, 12)])
def test_first_answer_and_updates_round_trip(mass, velocity, pressure, seed):
    rec = _record(mass, velocity, pressure, seed)
    stream, got = _stream(rec, window=0.03, cadence=0.005)
    stages = [est.details["stage"] for est in got]
    assert stages[0] == "first" and stages[-1] == "final" and set(stages[1:-1]) == {"update"}
    # the first answer reads the first window after first contact (a sample or two of trigger lead beyond it)
    assert got[0].available_at <= STAGES[0][0] + 1e-3
    cadence = np.diff([est.available_at for est in got[:-1]])
    assert cadence == pytest.approx(stream.cadence, abs=1.01 / rec.sample_rate)
    for est in got:
        assert est.method == "model/ml" and est.details["contact_law"] == "hysteretic"
        assert abs(est.mass - mass) <= Z * est.mass_std, est.details["stage"]
        assert abs(est.velocity - velocity) <= Z * est.velocity_std, est.details["stage"]
        assert est.details["update_time_s"] > 0 and est.details["cadence_s"] == stream.cadence
        assert isinstance(est.details, ModelDetails) and est.details.stream.stage == est.details["stage"]
    # the first answer with the stand's law; the others screened on the first window at the next update
    # (one at each update), and kept
    assert "screened on the first" in got[0].details["law_choice"]
    chosen = next(i for i, est in enumerate(got) if "only law left" in est.details["law_choice"])
    assert chosen == 2 and "kelvin-voigt: BIC" in got[chosen].details["law_choice"]
    assert all(est.details["law_choice"] == got[chosen].details["law_choice"] for est in got[chosen:-1])
    assert got[0].details["sigma_given"].startswith("the stand's parameters held")
    assert got[-2].details["sigma_given"] == "every unknown of the batch fit free"
    # the answers sharpen: the last update's σ of M1 is a fraction of the first's
    assert got[-2].mass_std < 0.5 * got[0].mass_std
    assert len(stream.update_times) == len(got) - 1


def test_an_earlier_first_window_answers_earlier_with_a_larger_sigma():
    rec = _record(30.0, 2.0, 100e3, 11, duration=0.012)
    early = _stream(rec, first=0.0025, window=0.011, cadence=0.005)[1][0]
    usual = _stream(rec, window=0.011, cadence=0.005)[1][0]
    assert early.available_at <= 0.0025 + 1e-3 < usual.available_at
    assert early.details["stage"] == "first" and early.mass_std > usual.mass_std
    assert abs(early.mass - 30.0) <= Z * early.mass_std and abs(early.velocity - 2.0) <= Z * early.velocity_std
    with pytest.raises(ParameterError, match="first must be"):
        ModelStream(50e3, first=0.001)


def test_a_record_of_another_law_than_the_stands_is_screened_at_once():
    # the stand's law (hysteretic) with its parameters held does not explain the first 4 ms of a Kelvin-Voigt
    # record: every law is fitted on that window before the first answer, and the screen keeps the record's
    rec = _record(25.0, 1.8, 150e3, 61, rig=get_rig(contact="kelvin-voigt"), duration=0.025)
    stream, got = _stream(rec, window=0.025)
    assert got[0].details["stage"] == "first" and got[0].available_at <= STAGES[0][0] + 1e-3
    assert "kelvin-voigt: the only law left" in got[0].details["law_choice"]
    assert "hysteretic: BIC" in got[0].details["law_choice"]
    for est in got[:-1]:
        assert est.details["contact_law"] == "kelvin-voigt"
        assert abs(est.mass - 25.0) <= Z * est.mass_std and abs(est.velocity - 1.8) <= Z * est.velocity_std


def test_the_final_answer_is_the_batch_fit_of_the_same_samples_whatever_the_chunks():
    rec = _record(30.0, 2.0, 100e3, 21)
    finals = []
    for chunk in (64, 4096):
        stream, got = _stream(rec, chunk=chunk, window=0.025)
        finals.append(got[-1])
        if chunk == 64:
            updates = [(est.mass, est.velocity, est.mass_std) for est in got[:-1]]
        else:  # chunks of any size give the same updates: each reads the record up to its own instant
            assert [(est.mass, est.velocity, est.mass_std) for est in got[:-1]] == updates
    final = finals[0]
    assert final.details["stage"] == "final" and final.mass == finals[1].mass
    # the samples it read: 20 ms before the trigger (0.3-0.6 ms after first contact) up to the window's end
    read = stream.last_record
    first = int(round((read.start_time - rec.start_time) * rec.sample_rate))
    stop = int(round((final.available_at - rec.start_time) * rec.sample_rate)) + 1
    assert stop - first == read.contact_force.size and read.start_time < -0.019
    cut = Recording(sample_rate=rec.sample_rate, start_time=rec.start_time + first / rec.sample_rate,
                    channels={name: rec.channel(name)[first:stop] for name in ("contact_force", "piston_acceleration")},
                    metadata=rec.metadata)
    batch = identify(cut)
    assert (final.mass, final.velocity, final.mass_std, final.velocity_std) == \
        (batch.mass, batch.velocity, batch.mass_std, batch.velocity_std)


def test_a_quiet_stream_has_no_answer():
    quiet = ModelStream(50e3)
    assert quiet.push(np.zeros(5000), np.zeros(5000)) == [] and quiet.finish() is None


def test_a_record_too_short_for_the_batch_fit_is_refused_at_finish():
    rec = _record(30.0, 2.0, 100e3, 41, duration=0.008)
    stream, got = _stream(rec)
    assert got and all(est.details["stage"] != "final" for est in got)
    with pytest.raises(IdentificationError, match="needs at least 10 ms"):
        stream.finish()


def test_bad_options_and_chunks_are_refused():
    with pytest.raises(ParameterError, match="cadence must be"):
        ModelStream(50e3, cadence=0.0)
    with pytest.raises(ParameterError, match="window must be"):
        ModelStream(50e3, window=0.005)
    with pytest.raises(ParameterError, match="contradicts"):
        ModelStream(50e3, metadata={"pressure_gauge_Pa": 100e3}, pressure_gauge=200e3)
    with pytest.raises(ParameterError, match="unknown stand parameter"):
        ModelStream(50e3, uncertain=["contact.colour"])
    with pytest.raises(IdentificationError, match="equal length"):
        ModelStream(50e3).push(np.zeros(3), np.zeros(4))
    ident = StreamingIdentifier(50e3)
    ident.push(np.zeros(10), np.zeros(10))
    with pytest.raises(IdentificationError, match="not in the buffer"):
        ident.buffered(5, 11)


def test_cli_stream_method_model(tmp_path, capsys):
    path = tmp_path / "drop.h5"
    write_recording(_record(30.0, 2.0, 100e3, 51, duration=0.02), path)
    main(["stream", str(path), "--method", "model", "--cadence", "5ms", "--json"])
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [line["stage"] for line in lines[:-1]] == ["first", "update", "update", "update", "final"]
    assert lines[-1]["kind"] == "summary" and lines[-1]["cadence_s"] == 0.005 and lines[-1]["updates"] == 3
    assert lines[-1]["update_time_median_s"] > 0 and lines[0]["sigma_given"]
    main(["stream", str(path), "--method", "model"])
    out = capsys.readouterr().out
    assert "updates every 10 ms of record" in out and "final answer of the stream (model" in out
    main(["stream", str(path), "--method", "model", "--first", "3ms", "--json"])
    assert json.loads(capsys.readouterr().out.splitlines()[0])["available_at_s"] < 0.004
    for args, message in ((["--cadence", "5ms"], "options of --method model"),
                          (["--method", "model", "--first", "20ms"], "--first"),
                          (["--method", "model", "--cadence", "0s"], "cadence"),
                          (["--method", "fast"], "--method must be one of")):
        with pytest.raises(SystemExit) as exc:
            main(["stream", str(path), *args])
        assert exc.value.code == 2 and message in capsys.readouterr().err


def test_two_impacts_in_one_stream_give_two_final_answers():
    first, second = _record(30.0, 2.0, 100e3, 81), _record(15.0, 1.5, 100e3, 82, duration=0.02)
    rng = np.random.default_rng(83)
    quiet = {name: np.std(first.channel(name)[:800]) * rng.standard_normal(25_000)  # 0.5 s: the trigger re-arms
             for name in ("contact_force", "piston_acceleration")}
    force, acceleration = (np.concatenate([first.channel(name), quiet[name], second.channel(name)])
                           for name in ("contact_force", "piston_acceleration"))
    stream = ModelStream(50e3, start_time=first.start_time, metadata=first.metadata, window=0.03)
    for k in range(0, force.size, 256):
        stream.push(force[k:k + 256], acceleration[k:k + 256])
    stream.finish()
    # the first impact's final answer at 30 ms of its record, the second's at the end of the stream
    assert len(stream.outcomes) == 2 and stream.outcomes[1].available_at > 0.5
    for outcome, (mass, velocity) in zip(stream.outcomes, ((30.0, 2.0), (15.0, 1.5)), strict=True):
        assert abs(outcome.mass - mass) <= Z * outcome.mass_std
        assert abs(outcome.velocity - velocity) <= Z * outcome.velocity_std


def test_an_impact_without_pre_trigger_gives_no_estimate_and_a_refusal():
    rec = _record(30.0, 2.0, 100e3, 91, duration=0.02, pre_trigger=0.0005)
    stream, got = _stream(rec)
    assert got == [] and stream.notes
    with pytest.raises(IdentificationError, match="pre-trigger"):
        stream.finish()


def test_a_deferred_update_reads_the_record_up_to_the_time_it_was_deferred_to():
    """A real-time caller whose last update was done at T: the next update reads the record up to T at least (the
    updates in between are skipped), then the cadence goes on from there."""
    rec = _record(30.0, 2.0, 100e3, 11, duration=0.03)
    stream = ModelStream(rec.sample_rate, start_time=rec.start_time, metadata=rec.metadata, window=0.029,
                         cadence=0.002)
    got = []
    for k in range(0, rec.contact_force.size, 16):
        new = stream.push(rec.contact_force[k:k + 16], rec.piston_acceleration[k:k + 16])
        if new and len(got) == 0:
            stream.defer(new[0].available_at + 0.007)
        got += new
    assert len(got) >= 3
    first, second, third = got[:3]
    assert second.available_at >= first.available_at + 0.007 - 1.0 / rec.sample_rate
    assert third.available_at == pytest.approx(second.available_at + 0.002, abs=1.5 / rec.sample_rate)


def _first_window(mass, velocity, pressure, seed):
    """A record's first 4 ms as the stream's first fit reads it, and the core layout started 20 % off in M1 and
    5 % in V0 (first contact at t = 0 on the record's clock)."""
    from impactometer.identify.model_fit import engine
    from impactometer.identify.model_fit.select import _Start, _start_law

    rec = _record(mass, velocity, pressure, seed)
    design = engine.anti_alias_design(rec)
    contact = 0.0
    data = engine.window(engine.observe(rec, design, contact, min_duration=0.0), contact + STAGES[0][0])
    start = _Start(mass=1.2 * mass, velocity=0.95 * velocity, contact_time=contact, pressure_gauge=pressure,
                  pressure_gauge_start=pressure)
    layouts, values = _start_law(get_rig(), get_rig().contact.law, None, start, rec.sample_rate)
    return data, layouts("core", values), values


def test_the_streams_predictions_on_the_calling_thread_equal_the_batch_fits():
    from impactometer.identify.model_fit.forward import _predict

    data, layout, values = _first_window(30.0, 2.0, 100e3, 21)
    rows = layout.variables(values)[None, :] + np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 1.5], [-1.0, 0.4, -2.0]])
    params, times = layout.packed(rows)
    assert np.array_equal(_predict(data.grid, params, times, in_turn=True), _predict(data.grid, params, times))
    for in_turn in (True, False):  # one range check
        with pytest.raises(IdentificationError, match="outside"):
            _predict(data.grid, *layout.packed(np.array([[-20.0, 0.0, 0.0]])), in_turn=in_turn)


@pytest.mark.parametrize(("mass", "velocity", "pressure", "seed"), [(30.0, 2.0, 100e3, 21), (10.0, 3.0, 400e3, 22)])
def test_the_engines_paths_agree(mass, velocity, pressure, seed):
    """The one solver run three ways on a first window (Python with predictions on the thread pool, Python on the
    calling thread, compiled) finds the same optimum, fitted to convergence and updated by one step."""
    from impactometer.identify.model_fit.engine import fit_law
    from impactometer.identify.model_fit.first_window import _fit_window, _takes

    data, layout, values = _first_window(mass, velocity, pressure, seed)
    assert _takes(data, layout)
    batch = fit_law(data, layout, values)
    python = fit_law(data, layout, values, in_turn=True)
    compiled = _fit_window(data, layout, values)
    assert batch.converged and python.converged and compiled.converged
    # the same predictions, the same arithmetic: equal to rounding
    assert python.chi2 == pytest.approx(batch.chi2, rel=1e-9)
    for name in ("mass", "velocity"):
        assert python.values[name] == pytest.approx(batch.values[name], rel=1e-9)
    # compiled: the last bit of M1 and V0 differs (its exp), and with it the finite-difference Jacobian's scatter
    # (engine.STEP: the integrator's step sequence changes with the point; 5 % here, where 4 ms tell M1 to 7 %)
    assert compiled.chi2 == pytest.approx(batch.chi2, rel=1e-6, abs=1e-3)
    for name in ("mass", "velocity"):
        assert abs(compiled.values[name] - batch.values[name]) <= 0.05 * batch.std(name)
        assert compiled.std(name) == pytest.approx(batch.std(name), rel=0.1)
    # an update from 2 % off: one step, on the thread pool, on the calling thread and compiled
    moved = {**batch.values, "mass": 1.02 * batch.values["mass"]}
    reference = fit_law(data, layout, moved, offsets=batch.offsets, jacobians=1)
    python = fit_law(data, layout, moved, offsets=batch.offsets, jacobians=1, in_turn=True)
    compiled = _fit_window(data, layout, moved, batch.offsets, jacobians=1)
    assert reference.chi2 < fit_law(data, layout, moved, offsets=batch.offsets, evaluations=1).chi2
    assert python.chi2 == pytest.approx(reference.chi2, rel=1e-9)
    assert python.std("mass") == pytest.approx(reference.std("mass"), rel=1e-6)
    for name in ("mass", "velocity"):
        assert python.values[name] == pytest.approx(reference.values[name], rel=1e-9)
        assert abs(compiled.values[name] - reference.values[name]) <= 0.05 * reference.std(name)


def test_the_compiled_fit_takes_every_layout_with_the_python_solvers_answer():
    """The stream's compiled fit answers the one solver's requests for any layout (the stand freed, the charge
    pressure with its prior): the same optimum as the solver in Python on the same residuals, within the stopping
    rule's reach (χ² to its tolerance, the values to a small fraction of their σ)."""
    from impactometer.identify.model_fit.first_window import _takes
    from impactometer.identify.model_fit.select import _Start, _start_law

    data, _, _ = _first_window(30.0, 2.0, 100e3, 21)
    start = _Start(mass=33.0, velocity=1.95, contact_time=0.0, pressure_gauge=100e3, pressure_gauge_start=100e3,
                  pressure_gauge_std=10e3)
    layouts, values = _start_law(get_rig(), get_rig().contact.law, None, start, data.grid.sample_rate)
    for kind in ("core", "all"):
        layout = layouts(kind, values)
        assert _takes(data, layout) and layout.priors and "pressure_gauge" in layout.names
        python, compiled = _same_optimum(data, layout, values)
        for name in ("mass", "velocity"):
            assert compiled.std(name) == pytest.approx(python.std(name), rel=0.1)


def _same_optimum(data, layout, start):
    """The Python solver's and the compiled fit's answers on ``layout``, asserted the same optimum within the
    stopping rule's reach (χ² to its tolerance, M1 and V0 to a small fraction of their σ)."""
    from impactometer.identify.model_fit.engine import TOLERANCE, fit_law
    from impactometer.identify.model_fit.first_window import _fit_window

    python = fit_law(data, layout, start, in_turn=True)
    compiled = _fit_window(data, layout, start)
    assert compiled.residuals == python.residuals
    assert compiled.chi2 == pytest.approx(python.chi2, rel=10 * TOLERANCE)
    for name in ("mass", "velocity"):
        assert abs(compiled.values[name] - python.values[name]) <= 0.1 * python.std(name)
    return python, compiled


def test_the_compiled_fit_keeps_a_layouts_own_bounds_as_the_python_solver_does():
    """A layout with bounds of its own (:meth:`Layout.with_bounds`) is fitted by the compiled fit with the one range
    check of the Python solver (a value outside the bounds packed as NaN and refused): the same optimum, inside the
    bounds, where a bound holds M1 below the free fit's answer, and on the contact instant."""
    from impactometer.identify.model_fit.engine import fit_law
    from impactometer.identify.model_fit.first_window import _takes
    from impactometer.model import dynamics as d

    data, layout, values = _first_window(30.0, 2.0, 100e3, 21)
    free = fit_law(data, layout, values, in_turn=True)
    ceiling = free.values["mass"] - 3.0 * free.std("mass")
    lead = values["contact_time"] - 2.0 / data.grid.sample_rate
    for bounded, start in ((layout.with_bounds("mass", 1.0, ceiling), {**values, "mass": 0.9 * ceiling}),
                           (layout.with_bounds("contact_time", lead, lead + 1.0), values)):
        assert _takes(data, bounded)
        for fit in _same_optimum(data, bounded, start):
            assert fit.values["contact_time"] >= lead
            if bounded.bounds[0][0] == "mass":
                assert fit.values["mass"] <= ceiling and fit.chi2 > free.chi2
    params, _ = layout.with_bounds("mass", 1.0, ceiling).packed(layout.variables({**values, "mass": 2 * ceiling}))
    assert np.isnan(params[0, d.MASS])  # outside: NaN, which the range check refuses


def test_the_one_solver_on_a_problem_with_a_known_answer():
    """The engine's solver on a linear problem reaches its least-squares answer (to the stopping rule's reach), reads
    the Jacobian through the normal equations only, and ends where the residuals cannot be evaluated (NaN or None)
    away from the start instead of looping."""
    from impactometer.identify.model_fit.engine import TOLERANCE, normal_equations, solve

    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(200, 4)), rng.normal(size=200)

    class Linear:
        def __init__(self, bad=None):
            self.bad = bad

        def residuals(self, x):
            if self.bad is not None and np.linalg.norm(x) > 1e-9:
                return None if self.bad == "none" else np.full(b.size, np.nan)
            return a @ x - b

        def jacobian(self, x):
            return a

        def normal(self, jac, r):
            return normal_equations(jac, r)

    exact = np.linalg.lstsq(a, b, rcond=None)[0]
    answer = solve(Linear(), np.zeros(4))
    best = float(np.sum(np.square(a @ exact - b)))
    assert answer.converged and answer.chi2 <= best * (1.0 + 10 * TOLERANCE)
    assert np.sqrt((answer.x - exact) @ (a.T @ a) @ (answer.x - exact)) <= np.sqrt(10 * TOLERANCE * best)
    for bad in ("nan", "none"):
        stuck = solve(Linear(bad), np.zeros(4))
        assert stuck.converged and np.array_equal(stuck.x, np.zeros(4)) and stuck.evaluations < 40


def test_a_prior_is_one_more_residual_row():
    """A Gaussian prior on a named unknown of the table: one residual row (variable − its mean)/σ'; a loose one
    leaves the answer, a tight one holds the unknown at its mean."""
    from impactometer.identify.model_fit.engine import Residuals, fit_law

    data, layout, values = _first_window(30.0, 2.0, 100e3, 21)
    free = fit_law(data, layout, values)
    loose = fit_law(data, layout.with_prior("velocity", 2.5, 1e3), values)
    tight = fit_law(data, layout.with_prior("velocity", 2.1, 1e-6), values)
    assert abs(loose.values["velocity"] - free.values["velocity"]) <= 0.05 * free.std("velocity")
    assert tight.values["velocity"] == pytest.approx(2.1, rel=1e-5) and tight.residuals == free.residuals + 1
    problem = Residuals(data, layout.with_prior("velocity", 2.1, 0.05))
    x = np.r_[layout.variables(values), data.offsets / data.noise]
    r, jac = problem.residuals(x), problem.jacobian(x)
    assert r[-1] == pytest.approx((x[1] - np.log(2.1)) / (0.05 / 2.1)) and jac[-1, 1] == pytest.approx(2.1 / 0.05)
    assert r.size == jac.shape[0] == Residuals(data, layout).residuals(x).size + 1


def test_without_robust_starts_the_stream_gives_the_same_answers():
    """The real-time loop's stream (``robust_starts=False``: the robust stream only triggers and buffers) answers
    as the default one does where no robust estimate comes before the first window's end."""
    rec = _record(30.0, 2.0, 100e3, 11, duration=0.03)
    options = {"window": 0.029, "cadence": 0.002, "first": 0.003}
    _, default = _stream(rec, **options)
    stream, bare = _stream(rec, robust_starts=False, **options)
    assert len(bare) == len(default) >= 5 and stream.robust.estimates == []
    for a, b in zip(default, bare, strict=True):
        assert (a.mass, a.velocity, a.available_at, a.method) == (b.mass, b.velocity, b.available_at, b.method)


def test_wrong_types_and_values_of_the_api_are_refused_naming_the_field():
    rec = _record(30.0, 2.0, 100e3, 61, duration=0.02)
    for call, field in ((lambda: identify(rec, uncertain=5), "uncertain"),
                        (lambda: ModelStream(50e3, metadata=[1]), "metadata")):
        with pytest.raises(ParameterTypeError, match=rf"^{field} must be .*, got ") as caught:
            call()
        assert isinstance(caught.value, TypeError) and caught.value.field == field
    with pytest.raises(ParameterError, match=r"at must be one of \['truth', 'estimate'\], got 'bogus'"):
        cramer_rao(rec, at="bogus")
    for flag in (True, np.bool_(False)):  # a flag is no pressure, not 1 Pa (nor 0 Pa)
        with pytest.raises(ParameterError, match=r"pressure_gauge must be a number within \[0, .*\[Pa gauge\].*got"):
            identify(rec, pressure_gauge=flag)
        with pytest.raises(ParameterError, match="pressure_gauge must be"):
            ModelStream(50e3, pressure_gauge=flag)
        with pytest.raises(ParameterError, match="mass must be"):
            cramer_rao(rec, mass=flag)
    for call in (lambda: identify(rec, pressure=100e3), lambda: ModelStream(50e3, pressure_std=1e3),
                 lambda: cramer_rao(rec, pressure_unknown=True)):  # a former name is refused naming the present one
        with pytest.raises(ParameterTypeError, match=r"^pressure\w* is now named pressure_gauge\w*: pass "):
            call()
    with pytest.raises(ParameterError, match=r"cadence must be > 0 \[s\], got 0"):
        check_schedule(cadence=0.0)  # without a sample rate: what the command line checks before reading
    assert check_schedule(cadence=0.005) == (0.005, STAGES[0][0], 0.05)


def test_a_push_after_finish_is_refused_by_the_model_stream():
    stream = ModelStream(50e3)
    stream.push(np.zeros(100), np.zeros(100))
    assert stream.finish() is None
    with pytest.raises(StreamFinishedError, match=r"push\(\) after finish\(\): this ModelStream"):
        stream.push(np.zeros(10), np.zeros(10))


def test_a_window_with_a_valve_opening_is_fitted_compiled_with_it():
    """A record that carries valve Z's opening is fitted by the compiled window fit, whose predictor reads the
    opening: the same optimum as the Python engine's on it (χ² to 10× the stopping rule's tolerance, M1 and V0 to
    a tenth of their σ), and another than the closed valve's."""
    import dataclasses

    from impactometer.identify.model_fit.first_window import _fit_window, _takes

    data, layout, values = _first_window(30.0, 2.0, 100e3, 21)
    for times, opening in (([1e-3], [0.5]), ([-1e-3, 2e-3], [0.3, 1.0])):  # opened after or before contact
        valve = (np.array(times), np.array(opening))
        opened = dataclasses.replace(data, grid=dataclasses.replace(data.grid, valve=valve))
        assert _takes(opened, layout)
        _, compiled = _same_optimum(opened, layout, values)
        assert compiled.chi2 != _fit_window(data, layout, values).chi2  # the opening changed the prediction


def test_an_opening_pushed_with_the_samples_is_checked_and_a_closed_valve_changes_nothing():
    """``push(force, acceleration, opening)``: an opening that is not finite, outside [0, 1] or of another length
    is refused naming it; an opening of zero throughout gives the answers of a stream without it, bit for bit."""
    stream = ModelStream(50e3)
    for bad, match in (([0.5, np.nan], "opening_chunk must be"), ([0.5, 1.5], "within \\[0, 1\\]"),
                       ([-0.1, 0.0], "got -0.1"), ([0.5], "length 2"), (["a", "b"], "must hold numbers")):
        with pytest.raises(IdentificationError, match=match):
            stream.push(np.zeros(2), np.zeros(2), bad)
    rec = _record(30.0, 2.0, 100e3, 11, duration=0.012)
    options = {"start_time": rec.start_time, "metadata": rec.metadata, "window": 0.011, "cadence": 0.004}
    plain, closed = ModelStream(rec.sample_rate, **options), ModelStream(rec.sample_rate, **options)
    zeros = np.zeros(rec.contact_force.size)
    got, same = [], []
    for k in range(0, zeros.size, 64):
        got += plain.push(rec.contact_force[k:k + 64], rec.piston_acceleration[k:k + 64])
        same += closed.push(rec.contact_force[k:k + 64], rec.piston_acceleration[k:k + 64], zeros[k:k + 64])
    assert len(got) == len(same) > 1
    for a, b in zip(got, same, strict=True):
        assert (a.mass, a.velocity, a.mass_std, a.available_at) == (b.mass, b.velocity, b.mass_std, b.available_at)
