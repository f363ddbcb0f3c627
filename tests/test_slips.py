"""A lab user's slips are named: an inverted force channel, a file without units, a sample rate that contradicts
the file's own, the paper variant on filtered channels."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from impactometer.errors import IdentificationError, RecordingError
from impactometer.filters import filter_recording
from impactometer.identify.peak_to_peak import identify
from impactometer.identify.peak_to_peak.segment import no_impact
from impactometer.io import read_recording, write_recording
from impactometer.rig import Scenario
from impactometer.sensors import record

TRUE_MASS, TRUE_VELOCITY = 25.0, 2.2


@pytest.fixture(scope="module")
def drop():
    """25 kg at 2.2 m/s onto the built-in stand, 1 % noise, 20 kHz, 50 ms after contact and 20 ms before."""
    return record(Scenario(mass=TRUE_MASS, velocity=TRUE_VELOCITY, pressure_gauge=200e3), sample_rate=20e3,
                  duration=0.05, noise=0.01, seed=3, pre_trigger=0.02)


def write_csv(path, header, rows):
    path.write_text(header + "\n" + "\n".join(",".join(f"{v:.9g}" for v in row) for row in rows) + "\n")
    return path


def test_an_inverted_force_channel_is_named_with_the_option_that_flips_it(drop):
    inverted = replace(drop, channels={**drop.channels, "contact_force": -drop.contact_force})
    with pytest.raises(IdentificationError, match=r"other sign.*--flip-force"):
        identify(inverted)
    # flipped back, the same record is answered
    flipped = replace(inverted, channels={**inverted.channels, "contact_force": -inverted.contact_force})
    assert identify(flipped).mass == pytest.approx(TRUE_MASS, rel=0.05)


def test_a_quiet_record_is_not_called_inverted():
    rng = np.random.default_rng(0)
    message = str(no_impact(rng.normal(0.0, 1.0, 4000)))
    assert "never leaves its noise" in message and "flip" not in message


def test_a_csv_in_ms_without_units_is_refused_naming_the_missing_units(tmp_path, drop):
    rows = np.column_stack([drop.time * 1e3, drop.contact_force / 1e3, drop.piston_acceleration / 9.80665])
    path = write_csv(tmp_path / "export.csv", "time,force,acceleration", rows)
    with pytest.raises(RecordingError, match=r"time column states no unit.*20 Hz.*brackets after each column name"):
        read_recording(path)
    # with the units in the header the same numbers are read as they are
    named = write_csv(tmp_path / "named.csv", "time [ms],force [kN],acceleration [g]", rows)
    rec = read_recording(named)
    assert rec.sample_rate == pytest.approx(20e3, rel=1e-6) and rec.units_note is None
    assert identify(rec).mass == pytest.approx(TRUE_MASS, rel=0.05)


def test_a_csv_in_seconds_without_units_is_read_with_a_note_in_the_answer(tmp_path, drop):
    rows = np.column_stack([drop.time, drop.contact_force, drop.piston_acceleration])
    rec = read_recording(write_csv(tmp_path / "bare.csv", "time,force,acceleration", rows))
    assert "states no units for 'force' as N" in rec.units_note
    answer = identify(rec)
    assert answer.mass == pytest.approx(TRUE_MASS, rel=0.05)
    assert any("states no units" in w for w in answer.warnings)


@pytest.mark.parametrize("extension", ["h5", "tdms", "mat", "csv"])
def test_a_sample_rate_that_contradicts_the_file_is_refused(tmp_path, drop, extension):
    path = write_recording(drop, tmp_path / f"drop.{extension}")
    with pytest.raises(RecordingError, match=r"50000 Hz \(--sample-rate\) disagrees with the .*20000 Hz"):
        read_recording(path, sample_rate=50e3)
    assert read_recording(path, sample_rate=20e3).sample_rate == pytest.approx(20e3)


def test_the_paper_variant_on_filtered_channels_carries_a_caution(drop):
    plain = identify(drop, variant="paper")
    filtered = identify(filter_recording(drop, 1000), variant="paper")
    assert "low-pass filtered" in filtered.details["caution"]
    assert "low-pass filtered" not in plain.details.get("caution", "")


def test_an_acceleration_in_g_under_an_m_s2_header_is_named_with_the_option_that_reads_it(tmp_path):
    """22 kg at 2 m/s exported in g under '[m/s^2]' gave 88.7 ± 0.9 kg and 0.19 m/s without a word."""
    rec = record(Scenario(mass=22.0, velocity=2.0, pressure_gauge=200e3), sample_rate=50e3, duration=0.07,
                 noise=0.01, seed=4, pre_trigger=0.02)
    rows = np.column_stack([rec.time - rec.time[0], rec.contact_force, rec.piston_acceleration / 9.80665])
    path = write_csv(tmp_path / "g.csv", "time [s],force [N],acceleration [m/s^2]", rows)
    slipped = identify(read_recording(path))
    assert any("an acceleration in g read as m/s²" in w and "--acceleration-unit g" in w for w in slipped.warnings)
    answer = identify(read_recording(path, acceleration_unit="g"))
    assert answer.mass == pytest.approx(22.0, rel=0.05) and answer.velocity == pytest.approx(2.0, rel=0.02)
    assert not any("read as" in w for w in answer.warnings)


def test_a_time_column_in_ms_under_an_s_header_is_refused_naming_the_unit_that_reads_it(tmp_path, drop):
    rows = np.column_stack([(drop.time - drop.time[0]) * 1e3, drop.contact_force, drop.piston_acceleration])
    path = write_csv(tmp_path / "ms.csv", "time [s],force [N],acceleration [m/s^2]", rows)
    with pytest.raises(RecordingError, match=r"gives 20 Hz over 70 s, no record of an impact.*--time-unit ms"):
        read_recording(path)
    rec = read_recording(path, time_unit="ms")
    assert rec.sample_rate == pytest.approx(20e3, rel=1e-6)
    with pytest.raises(RecordingError, match=r"time_unit must be a time unit \(s, ms"):
        read_recording(path, time_unit="kN")


def test_an_accelerometer_mounted_the_other_way_is_named_with_the_option_that_flips_it(drop):
    flipped = replace(drop, channels={**drop.channels, "piston_acceleration": -drop.piston_acceleration})
    with pytest.raises(IdentificationError, match=r"other sign.*--flip-acceleration"):
        identify(flipped)
