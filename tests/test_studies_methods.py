"""The identification methods of the noise and sampling studies: the ``model`` row next to ``paper`` and
``robust``, its refusals counted as failures, the ``methods`` setting (``--methods``), and chunks of a run with
other methods never reused."""

from __future__ import annotations

import math

import pytest

from impactometer.cli import main
from impactometer.errors import ParameterError
from impactometer.studies import StudyOptions, get_study, load_studies, run_study
from impactometer.studies.base import indexed_cases
from impactometer.studies.identification import failures, fallbacks
from impactometer.tables import pick, read_csv

load_studies()

#: one noise level on one channel target of the noise study: 3 records per case
NOISE = {"noise.levels": [0.05]}


pytestmark = pytest.mark.skipif(any(get_study(name).missing() for name in ("noise", "sampling")),
                                reason="the noise and sampling studies need modules not present in this tree")


def test_the_model_row_answers_a_noise_free_record_to_the_model_s_precision():
    study = get_study("sampling")
    options = StudyOptions(grid=2, params={"sampling.rates": [50e3]})
    rows = study.evaluate(indexed_cases(study, options)[:1], options)
    model = pick(rows, method="model")
    assert len(model) == 1 and model[0]["failure"] == "" and model[0]["path"] == "ml"
    # the record is the model's own, noise-free: M1 and V0 within 0.01 % (the robust answer is within ~0.1 %)
    assert abs(model[0]["mass_error"]) < 1e-4 and abs(model[0]["velocity_error"]) < 1e-4
    assert {r["method"] for r in rows} == {"paper", "robust-early", "robust", "model"}


def test_a_record_the_model_refuses_is_a_counted_failure_not_a_crash():
    study = get_study("noise")
    # no pre-trigger: the model cannot measure the noise of the channels, so it refuses every record
    options = StudyOptions(grid=2, pre_trigger=0.0, params=NOISE)
    rows = study.evaluate(indexed_cases(study, options)[:1], options)
    model = pick(rows, method="model")
    assert len(model) == 3
    for row in model:
        assert math.isnan(row["mass_estimate"]) and math.isnan(row["mass_error"]) and row["path"] == ""
        assert row["failure"].startswith("IdentificationError") and "before first contact" in row["failure"]
    assert failures(rows, method="model") == 3
    summary = study.summary(rows)
    failed = next(line for line in summary if line["quantity"].startswith("failed identifications"))
    assert "model 3 of 3" in failed["ours"]
    assert any(line["quantity"].startswith("model answers that fell back") for line in summary)
    table = {(r["method"], r["noise_on"]): r for r in study.aggregate(rows)}
    assert table[("model", "both")]["failed"] == 1 and table[("model", "both")]["n"] == 1


@pytest.mark.parametrize("name, params", [("noise", NOISE), ("sampling", {"sampling.rates": [50e3]})])
def test_the_methods_setting_chooses_the_rows(name, params):
    study = get_study(name)
    options = StudyOptions(grid=2, params={**params, f"{name}.methods": ["paper"]})
    rows = study.evaluate(indexed_cases(study, options)[:1], options)
    assert rows and {r["method"] for r in rows} == {"paper"}
    assert "path" not in rows[0] and fallbacks(rows) == 0
    assert not any(line["quantity"].startswith("model answers") for line in study.summary(rows))


def test_the_methods_in_effect_enter_the_options_key():
    # the defaults enter the key: giving them explicitly changes nothing, leaving the model out changes it
    default = StudyOptions(grid=2).key("noise")
    assert StudyOptions(grid=2, params={"noise.methods": ["paper", "robust", "model"]}).key("noise") == default
    assert StudyOptions(grid=2, params={"noise.methods": ["paper", "robust"]}).key("noise") != default
    # another study's setting does not
    assert StudyOptions(grid=2, params={"sampling.methods": ["paper"]}).key("noise") == default


def test_chunks_without_the_model_rows_are_not_reused(tmp_path):
    params = {**NOISE, "noise.chunk_size": 8}
    # a run as the studies ran before the model row: paper and robust only
    before = run_study("noise", tmp_path, StudyOptions(grid=2, params={**params, "noise.methods": ["paper", "robust"]}),
                       workers=1)
    assert {r["method"] for r in before.rows} == {"paper", "robust-early", "robust"}
    with pytest.raises(ParameterError, match="other options.*--overwrite"):
        run_study("noise", tmp_path, StudyOptions(grid=2, params=params), workers=1)


@pytest.mark.slow
def test_cli_study_noise_with_the_model_writes_its_rows_and_legend(tmp_path, capsys):
    main(["study", "noise", "--out", str(tmp_path), "--grid", "2", "--workers", "1", "--set", "noise.levels=[0.05]",
          "--methods", "robust,model"])
    capsys.readouterr()
    rows = read_csv((tmp_path / "noise.csv").read_text())
    assert {r["method"] for r in rows} == {"robust-early", "robust", "model"}
    assert len(pick(rows, method="model")) == 8 * 3
    assert all(r["path"] in ("ml", "fallback") for r in pick(rows, method="model"))
    assert (tmp_path / "noise.png").stat().st_size > 0
    from impactometer.plotting.studies import plot_noise

    fig = plot_noise(rows)
    labels = [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    assert "model" in labels and "robust" in labels
    import matplotlib.pyplot as plt

    plt.close(fig)


@pytest.mark.parametrize("argv, message", [
    (["--methods", "paper,magic"], "--methods must be a comma list of paper, robust, model, got 'paper,magic'"),
    (["--methods", ""], "--methods must be a comma list of paper, robust, model"),
])
def test_bad_methods_are_one_line_and_exit_2(argv, message, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["study", "noise", "--out", str(tmp_path), *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.startswith("error:") and err.count("\n") == 1 and message in err


def test_methods_on_a_study_without_them_is_refused(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["study", "peak-force", "--out", str(tmp_path), "--methods", "model"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "compares no identification methods" in err and "noise, sampling" in err
