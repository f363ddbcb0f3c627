"""``impactometer calibrate`` and ``impactometer validate``: a calibration set on disk calibrated, the stand file
used by ``validate`` and ``identify --method model``; bad input refused in one line with status 2, nothing
written."""

from __future__ import annotations

import csv
import dataclasses
import json

import pytest

from calibration_drops import BASE_STAND, CALIBRATION, HELD_BACK, drops
from impactometer.cli import main
from impactometer.io import write_recording
from impactometer.rig import get_rig

COLUMNS = ("file", "mass_kg", "velocity_m_s", "pressure_gauge_Pa")


def write_set(folder, recordings, *, manifest=True, truth=None):
    """Recordings as HDF5 files in ``folder`` with a manifest (``truth`` file -> row overrides)."""
    folder.mkdir()
    rows = []
    for i, rec in enumerate(recordings):
        name = f"drop{i + 1:02d}.h5"
        write_recording(rec, folder / name)
        rows.append({"file": name, **{k: rec.metadata.get(k) for k in COLUMNS[1:]}, **(truth or {}).get(name, {})})
    if manifest:
        with open(folder / "manifest.csv", "w", newline="") as f:
            writer = csv.DictWriter(f, COLUMNS)
            writer.writeheader()
            writer.writerows(rows)
    return folder


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("sets")
    base = BASE_STAND.to_toml(root / "base.toml")
    return {"calibration": write_set(root / "calibration", drops(CALIBRATION, noise=0.01, seed=1)),
            "held": write_set(root / "held", drops(HELD_BACK[:2], noise=0.05, seed=2)), "base": base, "root": root}


def _fails(capsys, argv, *expected):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error:"), err
    for text in expected:
        assert text in err, err
    return err


def test_calibrate_validate_identify(folders, tmp_path, capsys):
    out, plots = tmp_path / "lab.toml", tmp_path / "figures"
    main(["calibrate", str(folders["calibration"]), "--rig", str(folders["base"]), "--out", str(out), "--plot",
          str(plots), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert data["contact_law"] == "hysteretic" and data["fits"] and len(data["drops"]) == 6
    assert set(data["parameters"]) == {"contact.stiffness", "contact.restitution", "friction.force",
                                       "cylinder.dead_volume_lower", "cylinder.dead_volume_upper"}
    assert get_rig(str(out)).contact.law == "hysteretic"
    assert len(list(plots.glob("calibrate-*.png"))) == 7
    main(["validate", str(out), str(folders["held"]), "--json", "--plot", str(tmp_path / "validation")])
    result = json.loads(capsys.readouterr().out)
    assert result["median_force_nrmse"] <= 0.03 and len(result["drops"]) == 2
    main(["validate", str(out), str(folders["held"] / "drop01.h5"), str(folders["held"] / "drop02.h5")])
    assert "median force NRMSE" in capsys.readouterr().out  # files as well as a folder
    main(["identify", str(folders["held"] / "drop01.h5"), "--method", "model", "--rig", str(out), "--json"])
    answer = json.loads(capsys.readouterr().out)
    assert answer["method"] == "model" and answer["mass_kg"] == pytest.approx(HELD_BACK[0][0], rel=0.02)
    # the table, and the stand file refused without --overwrite
    main(["calibrate", str(folders["calibration"]), "--rig", str(folders["base"]), "--out", str(out), "--overwrite",
          "--fit", "contact,friction.force", "--contact", "hysteretic"])
    text = capsys.readouterr().out
    assert "contact.stiffness" in text and "stand written to" in text
    _fails(capsys, ["calibrate", str(folders["calibration"]), "--rig", str(folders["base"]), "--out", str(out)],
           "--overwrite")


def test_bad_input_one_line_nothing_written(folders, tmp_path, capsys):
    out = tmp_path / "cal.toml"
    calibration = str(folders["calibration"])
    bad = tmp_path / "bad.toml"
    bad.write_text("[cylinder]\nbore = 'wide'\n")
    _fails(capsys, ["calibrate", calibration, "--rig", str(bad), "--out", str(out)], "bore")
    _fails(capsys, ["calibrate", calibration, "--rig", str(folders["base"]), "--out", str(out), "--fit",
                    "contact.colour"], "--fit contact.colour", "unknown")
    _fails(capsys, ["calibrate", calibration, "--rig", str(folders["base"]), "--out", str(out), "--fit",
                    "cylinder.bore"], "cannot be fitted")
    few = write_set(tmp_path / "few", drops(CALIBRATION[:2], noise=0.01, seed=3))
    _fails(capsys, ["calibrate", str(few), "--rig", str(folders["base"]), "--out", str(out)], "needs at least 3")
    recordings = drops(CALIBRATION[:3], noise=0.01, seed=4)
    no_truth = write_set(tmp_path / "no_truth", [dataclasses.replace(r, metadata={}) for r in recordings],
                         manifest=False)
    _fails(capsys, ["calibrate", str(no_truth), "--rig", str(folders["base"]), "--out", str(out)], "no mass_kg")
    contradicting = write_set(tmp_path / "contradicting", recordings, truth={"drop02.h5": {"mass_kg": 99.0}})
    _fails(capsys, ["calibrate", str(contradicting), "--rig", str(folders["base"]), "--out", str(out)], "mass_kg")
    mixed = list(recordings)
    mixed[1] = dataclasses.replace(mixed[1], metadata={**mixed[1].metadata, "rig": "another-stand"})
    _fails(capsys, ["calibrate", str(write_set(tmp_path / "mixed", mixed)), "--rig", str(folders["base"]), "--out",
                    str(out)], "different stands")
    _fails(capsys, ["calibrate", calibration, "--rig", str(folders["base"]), "--out", str(out), "--velocity-sigma",
                    "0%"], "--velocity-sigma")
    _fails(capsys, ["validate", str(bad), str(folders["held"])], "bore")
    files = [str(folders["calibration"] / f"drop0{i}.h5") for i in (1, 2, 3)]
    _fails(capsys, ["calibrate", *files, "--manifest", str(folders["calibration"] / "manifest.csv"), "--out",
                    str(out)], "--manifest applies to a FOLDER")
    _fails(capsys, ["calibrate", files[0], str(folders["held"]), "--out", str(out)], "one FOLDER or recording files")
    assert not out.exists()


def test_targets_and_sets_refused_before_any_work(folders, tmp_path, capsys, monkeypatch):
    def no_fit(*args, **kwargs):
        raise AssertionError("a fit started")
    monkeypatch.setattr("impactometer.calibrate._fit_family", no_fit)
    calibration, base = str(folders["calibration"]), str(folders["base"])
    out = tmp_path / "cal.toml"
    _fails(capsys, ["calibrate", calibration, "--rig", base, "--out", str(tmp_path / "cal.txt")], "must end in .toml")
    _fails(capsys, ["calibrate", calibration, "--rig", base, "--out", base, "--overwrite"], "one of the inputs")
    _fails(capsys, ["calibrate", calibration, "--rig", base, "--out", str(out), "--plot", str(out)], "--out file")
    _fails(capsys, ["calibrate", calibration, "--rig", base, "--out", str(out), "--plot", calibration],
           "folder of recordings")
    files = [str(folders["calibration"] / f"drop0{i}.h5") for i in (1, 2, 3)]
    _fails(capsys, ["calibrate", *files, files[0], "--rig", base, "--out", str(out)], "one drop twice",
           "the same file")
    # the truth in the manifest only, one pressure written in kPa under the column in Pa
    recordings = drops(CALIBRATION[:3], noise=0.01, seed=4)
    truth = {f"drop{i + 1:02d}.h5": {k: r.metadata[k] for k in COLUMNS[1:]} for i, r in enumerate(recordings)}
    stated = truth["drop02.h5"]["pressure_gauge_Pa"] / 1e3
    truth["drop02.h5"]["pressure_gauge_Pa"] = stated
    kpa = write_set(tmp_path / "kpa", [dataclasses.replace(r, metadata={}) for r in recordings], truth=truth)
    _fails(capsys, ["calibrate", str(kpa), "--rig", base, "--out", str(out)], f"did you mean {stated:g}kPa")
    _fails(capsys, ["calibrate", calibration, "--rig", base, "--out", str(out), "--exclude", "nothing.h5"],
           "--exclude nothing.h5", "must name drops of the set")
    err = _fails(capsys, ["validate", str(folders["held"] / "drop01.h5"), str(folders["held"])], "stand TOML")
    assert "--rig" not in err
    assert not out.exists()


def test_tables_state_units_verdicts_and_progress(folders, tmp_path, capsys):
    out = tmp_path / "lab.toml"
    main(["calibrate", str(folders["calibration"]), "--rig", str(folders["base"]), "--out", str(out), "--contact",
          "hysteretic"])
    captured = capsys.readouterr()
    assert "cylinder.dead_volume_lower [cm³]" in captured.out  # headers may wrap at the piped width
    assert "gate" in captured.out and "pull" in captured.out and "[sigma]" in captured.out
    assert "consistent" in captured.out and "stand written to" in captured.out
    assert "stage 1 of" in captured.err  # off a terminal: one plain line per stage
    main(["validate", str(out), str(folders["held"])])
    text = capsys.readouterr().out
    assert "2 of 2 drops reproduced" in text and "NRMSE" in text and "range]" in text
