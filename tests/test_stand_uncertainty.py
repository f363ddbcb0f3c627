"""The calibrated stand's own uncertainty: stored in its stand file (``[uncertainty]``), read back, and carried into
σ(M1) and σ(V0) of a whole-record fit that holds those parameters.

The carried variance is S Σ_stand Sᵀ with S the fit's linear sensitivity to the held parameters: it grows with
Σ_stand (quadratically in its σ) and vanishes with it, leaving the answer unchanged.
"""

import math
import tomllib

import numpy as np
import pytest
import tomli_w

from impactometer.errors import ParameterError
from impactometer.identify.model_fit import identify
from impactometer.rig import Scenario, StandUncertainty, get_rig, load_uncertainty, save_toml
from impactometer.sensors import record

DEAD = ("cylinder.dead_volume_lower", "cylinder.dead_volume_upper")


def _uncertainty(rig, fraction, rho=0.3):
    return StandUncertainty(names=DEAD, std=(fraction * rig.cylinder.dead_volume_lower,
                                             fraction * rig.cylinder.dead_volume_upper),
                            correlation=np.array([[1.0, rho], [rho, 1.0]]))


def test_a_stand_file_round_trips_its_uncertainty(tmp_path):
    rig = get_rig("drop-stand")
    stated = _uncertainty(rig, 0.1)
    path = save_toml(rig, tmp_path / "lab.toml", uncertainty=stated)
    assert tomllib.loads(path.read_text())["uncertainty"]["names"] == list(DEAD)
    back = load_uncertainty(path)
    assert back is not None and back.names == stated.names and back.std == stated.std
    np.testing.assert_array_equal(back.correlation, stated.correlation)
    np.testing.assert_allclose(back.covariance(DEAD[::-1]), stated.covariance(DEAD)[::-1, ::-1])
    assert get_rig(str(path)) == rig  # the stand reads past the table
    assert load_uncertainty(save_toml(rig, tmp_path / "plain.toml")) is None  # a stand not calibrated states none


@pytest.mark.parametrize(("table", "match"), [
    ({"names": ["a"], "std": [-1.0], "correlation": [[1.0]]}, "std must hold one finite"),
    ({"names": ["a", "b"], "std": [1.0, 1.0], "correlation": [[1.0, 2.0], [2.0, 1.0]]}, "correlation must be"),
    ({"names": ["a"], "std": [1.0]}, "must be a table of names, std and correlation")])
def test_a_malformed_uncertainty_table_is_refused(tmp_path, table, match):
    path = tmp_path / "bad.toml"
    path.write_text(tomli_w.dumps({"name": "lab", "uncertainty": table}))
    with pytest.raises(ParameterError, match=match):
        load_uncertainty(path)


def test_the_stand_uncertainty_widens_sigma_and_leaves_the_answer(tmp_path):
    rig = get_rig("drop-stand")
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), rig, seed=5, sample_rate=50e3,
                 duration=0.05, noise=0.05, pre_trigger=0.02)
    plain = identify(rec, rig=rig, contact=rig.contact.law)
    tiny = identify(rec, rig=rig, contact=rig.contact.law, stand_uncertainty=_uncertainty(rig, 1e-9))
    path = save_toml(rig, tmp_path / "lab.toml", uncertainty=_uncertainty(rig, 0.1))
    wide = identify(rec, rig=str(path), contact=rig.contact.law)  # read from the stand file
    wider = identify(rec, rig=rig, contact=rig.contact.law, stand_uncertainty=_uncertainty(rig, 0.2))
    assert plain.method == tiny.method == wide.method == wider.method == "model/ml"
    for answer in (tiny, wide, wider):  # the answer itself is the fit's, whatever the stated σ
        assert answer.mass == plain.mass and answer.velocity == plain.velocity
    assert plain.details.stand_uncertainty is None
    assert tiny.mass_std == pytest.approx(plain.mass_std, rel=1e-9)
    assert tiny.velocity_std == pytest.approx(plain.velocity_std, rel=1e-9)
    assert wide.details.stand_uncertainty["parameters"] == list(DEAD)
    assert plain.mass_std < wide.mass_std < wider.mass_std
    assert plain.velocity_std < wide.velocity_std < wider.velocity_std
    # the carried σ adds in quadrature
    added = wide.details.stand_uncertainty["mass_std_kg"]
    assert wide.mass_std == pytest.approx(math.hypot(plain.mass_std, added), rel=1e-12)


def test_the_carried_sigma_is_what_a_refit_on_the_moved_stand_says():
    """One held parameter stated ± σ: the answer of fits on the stand with it moved by +σ and −σ differs by 2·S·σ,
    the σ carried. Each refit stops within Δχ² = 1e-6 χ² of its optimum (:data:`.engine.TOLERANCE`; ~0.007 on this
    record's 7000 residuals), so its M1 within ~0.12 of σ(M1): the half difference is compared to that."""
    rig = get_rig("drop-stand")
    name = "cylinder.dead_volume_upper"
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), rig, seed=5, sample_rate=50e3,
                 duration=0.05, noise=0.05, pre_trigger=0.02)
    value = rig.cylinder.dead_volume_upper
    carried = identify(rec, rig=rig, contact=rig.contact.law,
                       stand_uncertainty=StandUncertainty(names=(name,), std=(0.1 * value,), correlation=[[1.0]]))
    up, down = (identify(rec, rig=rig.replace(**{name: f * value}), contact=rig.contact.law) for f in (1.1, 0.9))
    added = carried.details.stand_uncertainty["mass_std_kg"]
    assert abs(up.mass - down.mass) / 2.0 == pytest.approx(added, abs=0.15 * carried.mass_std)
    assert added > 0.15 * carried.mass_std  # the comparison tells


def test_a_freed_parameter_is_not_carried_twice():
    rig = get_rig("drop-stand")
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), rig, seed=5, sample_rate=50e3,
                 duration=0.05, noise=0.05, pre_trigger=0.02)
    freed = identify(rec, rig=rig, contact=rig.contact.law, uncertain=["contact", *DEAD],
                     stand_uncertainty=_uncertainty(rig, 0.2))
    assert freed.details.stand_uncertainty is None  # the record fits them itself


def test_stand_uncertainty_must_be_one():
    rec = record(Scenario(mass=30.0, velocity=2.0, pressure_gauge=200e3), None, seed=5, sample_rate=50e3,
                 duration=0.05, noise=0.05, pre_trigger=0.02)
    with pytest.raises(ParameterError, match="stand_uncertainty must be a StandUncertainty"):
        identify(rec, stand_uncertainty={"names": DEAD})
