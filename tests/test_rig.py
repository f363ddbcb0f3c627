"""The stand description: presets, validation, dotted replacement and TOML round trips."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from impactometer.constants import STANDARD_GRAVITY
from impactometer.errors import ImpactometerError, ParameterError
from impactometer.rig import (
    PRESETS,
    Contact,
    Cylinder,
    Rig,
    Scenario,
    from_dict,
    get_rig,
    load_toml,
    parameter_names,
    save_toml,
    to_dict,
)


def test_pad_stand_is_the_paper_like_stand_and_the_default():
    rig = get_rig("drop-stand-pad")
    assert rig is PRESETS["drop-stand-pad"] and rig.name == "drop-stand-pad"
    default = get_rig()  # the default stand is the pad stand under its own name
    assert default is PRESETS["drop-stand"] and dataclasses.replace(default, name="drop-stand-pad") == rig
    c = rig.cylinder
    assert (c.piston_mass, c.bore, c.rod_diameter, c.stroke, c.lower_length, c.upper_length) == \
        (4.0, 0.08, 0.025, 0.20, 0.20, 0.02)
    assert c.area == pytest.approx(math.pi * 0.04**2)
    assert c.annulus_area == pytest.approx(math.pi * (0.04**2 - 0.0125**2))
    assert (rig.gas.gamma, rig.gas.atmospheric_pressure, rig.gravity) == (1.4, 101325.0, STANDARD_GRAVITY)
    assert (rig.friction.force, rig.friction.velocity_scale) == (200.0, 0.01)
    assert (rig.contact.law, rig.contact.stiffness, rig.contact.restitution) == ("hysteretic", 7e5, 0.4)
    assert rig.contact.damping is None and rig.contact.unloading_stiffness == pytest.approx(7e5 / 0.4**2)
    assert (c.dead_volume_lower, c.dead_volume_upper) == (2e-5, 1e-5)
    assert (rig.stops.stiffness, rig.stops.damping) == (5e7, 2e3)


def test_stiff_preset_is_the_earlier_stand():
    stiff = get_rig("drop-stand-stiff")
    assert stiff.name == "drop-stand-stiff"
    assert (stiff.contact.law, stiff.contact.stiffness, stiff.contact.damping) == ("kelvin-voigt", 2e6, 150.0)
    assert stiff.friction.force == 30.0 and stiff.contact.restitution is None
    assert (stiff.cylinder.dead_volume_lower, stiff.cylinder.dead_volume_upper) == (0.0, 0.0)
    pad = get_rig("drop-stand-pad")
    assert dataclasses.replace(stiff.cylinder, dead_volume_lower=2e-5, dead_volume_upper=1e-5) == pad.cylinder
    assert stiff.gas == pad.gas
    assert dataclasses.replace(Rig(), name="drop-stand-pad") == pad  # the parts' defaults are the pad stand's


@pytest.mark.parametrize("section, message", [
    ({"law": "hysteretic", "restitution": 0.0}, "contact.restitution must be > 0"),
    ({"law": "hysteretic", "restitution": 1.2}, "softer than the loading line"),
    ({"law": "hysteretic", "stiffness": -1.0}, "contact.stiffness must be > 0"),
    ({"law": "hysteretic", "damping": 150.0}, "contact.damping is not a parameter of the hysteretic"),
    ({"law": "kelvin-voigt", "restitution": 0.5}, "contact.restitution is not a parameter of the kelvin-voigt"),
    ({"law": "rubber"}, "contact.law must be one of"),
    ({"law": "hysteretic", "restitution": "half"}, "contact.restitution must be a finite number"),
])
def test_bad_contact_sections_name_the_field(section, message):
    from impactometer.rig import from_dict

    with pytest.raises(ParameterError, match=message):
        from_dict({"contact": section})


def test_a_law_change_keeps_only_the_new_laws_parameters():
    kv = get_rig("drop-stand-pad").replace(**{"contact.law": "kv"}).contact
    assert (kv.law, kv.stiffness, kv.damping, kv.restitution) == ("kelvin-voigt", 2e6, 150.0, None)
    hys = get_rig("drop-stand-stiff").replace(**{"contact.law": "hysteretic", "contact.restitution": 0.6}).contact
    assert (hys.stiffness, hys.restitution, hys.damping) == (7e5, 0.6, None)


@pytest.mark.parametrize("name, law, stiffness, damping", [
    ("hunt", "hunt-crossley", 4e8, 0.2), ("hc", "hunt-crossley", 4e8, 0.2), ("kv", "kelvin-voigt", 2e6, 150.0),
    ("Kelvin-Voigt", "kelvin-voigt", 2e6, 150.0)])
def test_contact_law_by_name_or_alias(name, law, stiffness, damping):
    contact = get_rig(contact=name).contact
    assert (contact.law, contact.stiffness, contact.damping) == (law, stiffness, damping)


def test_replace_by_dotted_names():
    rig = get_rig().replace(**{"contact.stiffness": 3e6, "gravity": 0.0, "cylinder.dead_volume_lower": 1e-4})
    assert (rig.contact.stiffness, rig.gravity, rig.cylinder.dead_volume_lower) == (3e6, 0.0, 1e-4)
    assert get_rig().contact.stiffness == 7e5  # frozen original unchanged


def test_changing_the_law_takes_its_defaults_unless_given():
    assert get_rig().replace(**{"contact.law": "hunt"}).contact == Contact.preset("hunt-crossley")
    custom = get_rig().replace(**{"contact.law": "hunt", "contact.damping": 0.3}).contact
    assert (custom.stiffness, custom.damping) == (4e8, 0.3)


@pytest.mark.parametrize("key", ["contact.stifness", "foo.bar", "cylinder", "a.b.c", "stiffness"])
def test_replace_rejects_unknown_parameters(key):
    with pytest.raises(ParameterError, match=f"unknown rig parameter '{key}'"):
        get_rig().replace(**{key: 1.0})


def test_parameter_names_all_replaceable():
    rig = get_rig()
    for name in parameter_names():
        section, _, attr = name.rpartition(".")
        value = getattr(getattr(rig, section), attr) if section else getattr(rig, attr)
        assert rig.replace(**{name: value}) == rig


@pytest.mark.parametrize("changes, match", [
    ({"cylinder.rod_diameter": 0.08}, r"cylinder.rod_diameter must be < bore \(0.08 m\), got 0.08"),
    ({"cylinder.rod_diameter": 0.1}, "cylinder.rod_diameter must be < bore"),
    ({"cylinder.lower_length": 0.0, "cylinder.dead_volume_lower": 0.0}, "lower chamber has zero gas volume"),
    ({"cylinder.upper_length": 0.0, "cylinder.dead_volume_upper": 0.0}, "upper chamber has zero gas volume"),
    ({"cylinder.stroke": 0.3}, "cylinder.stroke must not exceed the lower gas column"),
    ({"cylinder.piston_mass": 0.0}, r"cylinder.piston_mass must be > 0, got 0.0"),
    ({"cylinder.bore": float("nan")}, "cylinder.bore must be a finite number, got nan"),
    ({"gas.gamma": 2.0}, "gas.gamma must be <= 1.66667"),
    ({"friction.force": -1.0}, "friction.force must be >= 0"),
    ({"contact.stiffness": -1.0}, "contact.stiffness must be > 0"),
    ({"contact.law": "maxwell"}, "contact.law must be one of"),
    ({"stops.damping": "a lot"}, "stops.damping must be a finite number, got 'a lot'"),
    ({"valve.area": 1.0}, "valve.area must be <= 0.0002"),
    ({"gravity": -9.81}, "rig.gravity must be >= 0"),
    ({"name": 3}, "rig.name must be a string"),
])
def test_invalid_stand_is_a_parameter_error(changes, match):
    with pytest.raises(ParameterError, match=match):
        get_rig().replace(**changes)


def test_sections_are_keyword_only_and_typed():
    with pytest.raises(TypeError):
        Cylinder(4.0)  # positional arguments are not accepted
    with pytest.raises(ParameterError, match="rig.cylinder must be a Cylinder"):
        Rig(cylinder={"bore": 0.1})


@pytest.mark.parametrize("kwargs, match", [
    ({"mass": 0.0, "velocity": 2.0}, r"mass must be >= 0.1 \[kg\], got 0.0"),
    ({"mass": -3.0, "velocity": 2.0}, "mass must be >= 0.1"),
    ({"mass": 1e-9, "velocity": 2.0}, "mass must be >= 0.1"),
    ({"mass": 2e4, "velocity": 2.0}, r"mass must be <= 10000 \[kg\]"),
    ({"mass": 30.0, "velocity": 30.0}, r"velocity must be <= 15.3\d* \[m/s\]"),
    ({"mass": float("nan"), "velocity": 2.0}, r"mass must be a finite number \[kg\], got nan"),
    ({"mass": 30.0, "velocity": 0.0}, r"velocity must be > 0 \[m/s\]"),
    ({"mass": 30.0, "velocity": float("inf")}, "velocity must be a finite number"),
    ({"mass": 30.0, "velocity": 2.0, "pressure_gauge": -1.0}, r"pressure_gauge must be >= 0 \[Pa\]"),
    ({"mass": "30kg", "velocity": 2.0}, "mass must be a finite number"),
])
def test_invalid_scenario_is_a_parameter_error(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        Scenario(**kwargs)


@pytest.mark.parametrize("height", [0.0, -0.2, float("nan")])
def test_invalid_height(height):
    with pytest.raises(ParameterError, match="height must be"):
        Scenario.from_height(mass=30.0, height=height)


def test_scenario_from_height_and_numpy_scalars():
    s = Scenario.from_height(mass=np.float32(30.0), height=0.2, pressure_gauge=np.int64(200_000))
    assert s.velocity == pytest.approx(math.sqrt(2 * STANDARD_GRAVITY * 0.2))


def test_pressure_above_rating():
    with pytest.raises(ParameterError, match="pressure_gauge must be <= the rated 400000 Pa of 'drop-stand'"):
        Scenario(mass=30.0, velocity=2.0, pressure_gauge=401e3).check_against(get_rig())


def test_errors_are_value_errors():
    with pytest.raises(ValueError):
        Scenario(mass=-1.0, velocity=1.0)
    assert issubclass(ParameterError, ImpactometerError)


def test_toml_round_trip(tmp_path):
    rig = get_rig(contact="hunt").replace(**{"name": "my stand", "cylinder.dead_volume_upper": 2e-5,
                                             "friction.force": 12.5, "gravity": 9.80665})
    path = save_toml(rig, tmp_path / "stand.toml")
    assert load_toml(path) == rig
    assert get_rig(path) == rig
    assert from_dict(to_dict(rig)) == rig


def test_power_law_contact_round_trips_through_toml(tmp_path):
    """The power law's exponents and plastic set are written, read back exactly, and only they are written."""
    rig = get_rig().replace(**{"contact.law": "masing", "contact.stiffness": 3.3e7, "contact.exponent": 1.8,
                               "contact.unloading_exponent": 4.25, "contact.set_fraction": 0.35})
    path = save_toml(rig, tmp_path / "stand.toml")
    assert load_toml(path) == rig
    assert to_dict(rig)["contact"] == {"law": "power", "stiffness": 3.3e7, "exponent": 1.8,
                                       "unloading_exponent": 4.25, "set_fraction": 0.35}
    partial = tmp_path / "partial.toml"
    partial.write_text('[contact]\nlaw = "power"\nexponent = 2.0\n', encoding="utf-8")
    assert load_toml(partial).contact == Contact(law="power", exponent=2.0)


def test_toml_refuses_to_overwrite(tmp_path):
    path = get_rig().to_toml(tmp_path / "stand.toml")
    with pytest.raises(ParameterError, match="exists; pass overwrite=True"):
        get_rig().to_toml(path)
    get_rig(contact="hunt").to_toml(path, overwrite=True)
    assert load_toml(path).contact.law == "hunt-crossley"


def test_partial_toml_takes_defaults_and_law_defaults(tmp_path):
    path = tmp_path / "partial.toml"
    path.write_text('gravity = 9.8\n[contact]\nlaw = "hunt"\n[cylinder]\nbore = 0.1\n', encoding="utf-8")
    rig = load_toml(path)
    assert rig.gravity == 9.8 and rig.cylinder.bore == 0.1 and rig.cylinder.stroke == 0.2
    assert rig.contact == Contact.preset("hunt-crossley")


@pytest.mark.parametrize("text, match", [
    ("[cylinder]\nbroe = 0.1\n", r"unknown key\(s\) \['cylinder.broe'\]; expected"),
    ("[cylindre]\nbore = 0.1\n", r"unknown key\(s\) \['cylindre'\]"),
    ("gravty = 9.8\n", r"unknown key\(s\) \['gravty'\]"),
    ("cylinder = 3\n", r"\[cylinder\] must be a table"),
    ("[cylinder]\nbore = \"wide\"\n", "cylinder.bore must be a finite number, got 'wide'"),
    ("[contact]\nlaw = \"rubber\"\n", "contact.law must be one of"),
    ("[cylinder\nbore = 0.1\n", "is not valid TOML"),
    ("[cylinder]\nrod_diameter = 0.09\n", "cylinder.rod_diameter must be < bore"),
])
def test_bad_toml_is_a_parameter_error_naming_the_file(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ParameterError, match=match) as caught:
        load_toml(path)
    assert str(path) in str(caught.value)


@pytest.mark.parametrize("text", ["", "# nothing yet\n", "[provenance]\nsource = \"x\"\n"])
def test_a_toml_without_stand_parameters_is_refused_not_taken_for_the_built_in_stand(tmp_path, text):
    path = tmp_path / "lab.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ParameterError, match=r"lab.toml' holds no stand; expected a stand description"):
        get_rig(path)


def test_a_bad_field_of_a_stand_file_is_reported_as_the_file_not_as_an_option(tmp_path):
    """On the command line the error names the option that gave the file (--rig), the file and its field, not
    the option the field stands for elsewhere (--contact)."""
    from impactometer.cli.app import given

    path = tmp_path / "lab.toml"
    path.write_text('[contact]\nlaw = "rubber"\n', encoding="utf-8")
    with pytest.raises(ParameterError) as caught, given(rig=str(path), contact="auto"):
        get_rig(str(path))
    assert str(caught.value).startswith(f"--rig {path}: contact.law must be one of") and "--contact" not in str(
        caught.value)
    assert caught.value.field == "rig"


def test_get_rig_errors(tmp_path):
    with pytest.raises(ParameterError,
                       match=r"rig must be one of \['drop-stand', 'drop-stand-pad', "
                             r"'drop-stand-stiff'\] or a .toml file"):
        get_rig("tower")
    with pytest.raises(ParameterError, match="does not exist"):
        get_rig(tmp_path / "missing.toml")
    with pytest.raises(ParameterError, match="contact.law must be one of"):
        get_rig(contact="glue")


def _rig_show(args, capsys):
    from test_cli_simulate import run

    return run(["rig", "show", *args], capsys)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_rig_show_writes_every_preset_as_a_file_that_reads_back_as_it(name, tmp_path, capsys):
    status, printed, err = _rig_show([name], capsys)
    assert status == 0 and err == "", err
    path = tmp_path / "base.toml"
    status, out, err = _rig_show([name, "--out", str(path)], capsys)
    assert status == 0 and str(path) in out, err
    assert path.read_text(encoding="utf-8") == printed and printed.startswith(f"# The stand {name}, written by")
    assert load_toml(path) == PRESETS[name]
    status, out, err = _rig_show([name, "--out", str(path)], capsys)  # a saved file is never replaced unasked
    assert status == 2 and "exists; pass --overwrite" in err and out == ""
    assert _rig_show([name, "--out", str(path), "--overwrite", "--contact", "kv"], capsys)[0] == 0
    assert load_toml(path) == PRESETS[name].with_contact("kv")


def test_rig_show_refuses_what_is_no_stand(tmp_path, capsys):
    status, out, err = _rig_show(["tower"], capsys)
    assert status == 2 and "tower" in err and "drop-stand" in err and out == ""
    status, out, err = _rig_show(["drop-stand", "--out", str(tmp_path / "base.txt")], capsys)
    assert status == 2 and "expected one of .toml" in err and not (tmp_path / "base.txt").exists()


def test_the_stand_file_in_the_docs_is_what_rig_show_prints(capsys):
    """docs/simulation.md shows the built-in stand's file as `impactometer rig show drop-stand` prints it."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "simulation.md").read_text(encoding="utf-8")
    block = doc.split("<!-- rig show drop-stand -->\n```toml\n", 1)[1].split("```\n", 1)[0]
    status, printed, _ = _rig_show(["drop-stand"], capsys)
    assert status == 0 and block == printed
