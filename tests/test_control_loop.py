"""The closed loop identify → control, the absorb CLI and the absorption table."""

import json
import math

import numpy as np
import pytest

from impactometer.cli import main
from impactometer.control import loop as control_loop
from impactometer.control.loop import Identified, absorb
from impactometer.control.study import absorption_table, acceptance_summary, grid_cases
from impactometer.control.valve import Absorber
from impactometer.errors import ParameterError
from impactometer.rig import Scenario

SCENARIO = Scenario.from_height(mass=30.0, height=0.3, pressure_gauge=200e3)


@pytest.fixture(scope="module")
def oracle_run():
    return absorb(SCENARIO, strategy=["closed", "realtime"], identification="oracle", noise=0.0)


def test_realtime_stops_the_mass_at_the_end_of_the_usable_stroke_without_rebound(oracle_run):
    usable = oracle_run.absorber.usable_stroke(oracle_run.rig)
    run = oracle_run.runs["realtime"]
    m = run.metrics
    # within the usable stroke (+ 2 mm: contact compression and the final approach), never on the bottom stop
    assert usable - 0.01 < m.stroke_used < usable + 0.002
    assert not m.bottomed_out
    assert m.rebound < 1e-3
    # on the last part of the stroke the contact force holds the level F* = M1·(v²/(2·s) + g) within 10 %
    i = int(np.argmax(run.result.u1 > 0.95 * usable))
    assert run.result.contact_force[i] == pytest.approx(run.controller["target_force"][i], rel=0.1)


def test_realtime_lowers_the_peak_and_uses_more_stroke_than_the_gas_spring(oracle_run):
    closed, realtime = oracle_run.metrics["closed"], oracle_run.metrics["realtime"]
    assert realtime.peak_force_controlled < 0.9 * closed.peak_force_controlled
    assert realtime.stroke_used > 2.0 * closed.stroke_used
    assert closed.rebounded and closed.rebound > 0.1  # the gas spring throws the mass back up
    assert realtime.peak_force_stage_a == closed.peak_force_stage_a  # stage A comes before the control
    assert 0.0 < oracle_run.bound.efficiency <= 1.0


def test_first_collision_reference_explains_the_realtime_efficiency(oracle_run):
    closed, realtime = oracle_run.metrics["closed"], oracle_run.metrics["realtime"]
    bound = oracle_run.bound
    # the piston flies off the mass at the control start: bounce energy ½·μ·w² well above zero
    assert realtime.bounce_energy == closed.bounce_energy > 1.0
    # opening fully at the control start lowers the next collision below the gas spring's, but it stays far above
    # the bound's constant level
    assert 3.0 * bound.level < bound.first_collision_peak < closed.peak_force_controlled
    assert bound.efficiency_first_collision < 0.5 * bound.efficiency
    # the real-time strategy's peak is that first collision, so its efficiency is the reference's (within 10 %)
    assert realtime.peak_force_controlled == pytest.approx(bound.first_collision_peak, rel=0.1)
    assert realtime.efficiency == pytest.approx(bound.efficiency_first_collision, rel=0.1)


def test_identification_failure_leaves_the_valve_closed(monkeypatch):
    failed = Identified(method="robust", mass=math.nan, velocity=math.nan, available_at=math.inf,
                        error="fewer pulses than needed")
    monkeypatch.setattr(control_loop, "identify_impact", lambda *a, **k: failed)
    result = absorb(SCENARIO, strategy=["closed", "realtime"], noise=0.02, duration=0.1)
    assert any("identification failed" in note for note in result.notes)
    assert np.array_equal(result.runs["realtime"].result.u1, result.runs["closed"].result.u1)
    assert result.to_dict()["strategies"]["realtime"]["control_start_s"] is None


def test_over_capacity_is_reported():
    result = absorb(SCENARIO, strategy="closed", identification="oracle", absorber=Absorber(rated_force=200.0),
                    duration=0.1)
    assert result.over_capacity
    assert any("above the rated 200 N" in note for note in result.notes)


@pytest.mark.parametrize("kwargs, match", [
    ({"strategy": "open"}, "strategy must be one of"), ({"identification": "guess"}, "identification"),
    ({"noise": -0.1}, "noise"), ({"seed": -1}, "seed"), ({"absorber": "big"}, "absorber"),
    ({"control_start": math.nan}, "control_start"), ({"duration": -1.0}, "duration")])
def test_invalid_absorb_arguments(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        absorb(SCENARIO, **kwargs)


def test_noisy_loop_is_reproducible_and_seeded():
    a = absorb(SCENARIO, strategy="realtime", identification="oracle", noise=0.02, seed=3, duration=0.15)
    b = absorb(SCENARIO, strategy="realtime", identification="oracle", noise=0.02, seed=3, duration=0.15)
    c = absorb(SCENARIO, strategy="realtime", identification="oracle", noise=0.02, seed=4, duration=0.15)
    assert a.to_dict() == b.to_dict()
    assert not np.array_equal(a.runs["realtime"].result.u1, c.runs["realtime"].result.u1)


def test_absorption_table_rows_and_summary():
    cases = grid_cases(5)[62:63]  # the centre of the grid: 30 kg, 2 m/s, 210 kPa
    rows = absorption_table(cases, noise=0.02, seed=0)
    assert [r["strategy"] for r in rows] == ["closed", "constant", "realtime", "realtime (oracle)"]
    assert {r["mass_kg"] for r in rows} == {30.0}
    summary = acceptance_summary(rows)
    assert summary["cases"] == 1
    assert 0.0 < summary["realtime (oracle): median efficiency"] <= 1.0
    assert len(grid_cases(5)) == 125


def test_cli_absorb_json_and_plot(tmp_path, capsys):
    figure = tmp_path / "fig10.png"
    main(["absorb", "--mass", "30kg", "--height", "0.3m", "--pressure", "200kPa", "--strategy", "realtime",
          "--identify", "oracle", "--json", "--plot", str(figure)])
    data = json.loads(capsys.readouterr().out)
    keys = {"peak_force_stage_a_N", "peak_force_controlled_N", "efficiency", "stroke_used_m", "bottomed_out",
            "control_start_s"}
    assert keys <= set(data["strategies"]["realtime"])
    assert figure.stat().st_size > 10_000
    with pytest.raises(SystemExit) as exit_info:
        main(["absorb", "--strategy", "closed", "--identify", "oracle", "--plot", str(figure)])
    assert exit_info.value.code == 2
    assert "--force" in capsys.readouterr().out


def test_cli_absorb_table(capsys):
    main(["absorb", "--strategy", "closed", "--identify", "oracle"])
    out = capsys.readouterr().out
    assert "peak force after control start [N]" in out and "rebound [mm]" in out


@pytest.mark.parametrize("args, match", [
    (["--strategy", "open"], "strategy must be one of"), (["--identify", "guess"], "identification"),
    (["--noise", "-3%"], "noise"), (["--mass", "-30kg"], "mass"),
    (["--response-map", "map.h5"], "--identify response-map")])
def test_cli_absorb_bad_input(args, match, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["absorb", *args])
    assert exit_info.value.code == 2
    assert match in capsys.readouterr().out


def test_distribution_figure(tmp_path):
    from impactometer.control.plots import plot_distributions

    rows = [{"mass_kg": 30.0, "velocity_m_s": 2.0, "pressure_gauge_Pa": 2e5, "strategy": name, "efficiency": eff,
             "efficiency_max": 0.9, "peak_force_controlled_N": 1e3 / eff, "stroke_used_m": 0.1}
            for name, eff in (("closed", 0.3), ("realtime", 0.6))]
    fig = plot_distributions(rows)
    assert [a.get_title() for a in fig.axes] == ["efficiency", "peak_force_controlled_N", "stroke_used_m"]
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == ["closed", "realtime", "bound η_max"]
    fig.savefig(tmp_path / "d.png")


def test_loop_with_a_response_map():
    from impactometer.identify.response_map_build import build_map_simulated

    rmap = build_map_simulated(pressure_gauge=200e3, masses=np.linspace(10, 50, 21), velocities=np.linspace(1, 3, 21))
    scenario = Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3)
    result = absorb(scenario, strategy="realtime", identification="response-map", response_map=rmap, duration=0.1)
    assert result.identified.method == "response-map" and result.identified.error is None
    # the map identifies the impact to a few percent at 2 % noise, within the first pulses
    assert result.identified.mass == pytest.approx(30.0, rel=0.05)
    assert result.identified.velocity == pytest.approx(2.0, rel=0.02)
    assert 0.0 < result.control_start < 0.05
    with pytest.raises(ParameterError, match="response_map"):
        absorb(scenario, strategy="realtime", identification="response-map", duration=0.1)
