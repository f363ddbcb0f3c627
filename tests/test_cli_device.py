"""``--device`` of ``impactometer map build`` and ``impactometer study``, run in-process."""

from __future__ import annotations

import os

import pytest

from impactometer.identify.response_map import load_map
from impactometer.model import gpu
from test_cli_simulate import assert_error_line, run

NO_GPU = "no usable CUDA GPU (no device found)"


@pytest.fixture
def no_gpu(monkeypatch):
    monkeypatch.setattr(gpu, "unavailable_reason", lambda: NO_GPU)


@pytest.mark.parametrize("argv", [
    ["map", "build", "--grid", "3x3", "--device", "gpu"],
    ["study", "peak-force", "--grid", "2", "--workers", "1", "--device", "gpu"],
])
def test_gpu_without_a_gpu_is_one_line_naming_the_extra_and_exit_2(argv, tmp_path, capsys, no_gpu):
    status, out, err = run([*argv, "--out", str(tmp_path / "x")], capsys)
    assert_error_line(status, out, err)  # refused before any progress is printed
    line = err.splitlines()[-1]
    assert "impactometer[gpu]" in line and NO_GPU in line and "Traceback" not in out + err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("argv", [
    ["map", "build", "--grid", "3x3", "--device", "tpu"],
    ["study", "peak-force", "--grid", "2", "--workers", "1", "--device", "tpu"],
])
def test_unknown_device_is_exit_2(argv, tmp_path, capsys):
    status, out, err = run([*argv, "--out", str(tmp_path / "x")], capsys)
    assert_error_line(status, out, err)
    assert "--device tpu: must be one of ['cpu', 'gpu', 'auto']" in err.splitlines()[-1]


def test_map_build_on_auto_falls_back_to_the_cpu(tmp_path, capsys, no_gpu):
    out = tmp_path / "map.h5"
    status, text, err = run(["map", "build", "--grid", "4x3", "--device", "auto", "--out", str(out)], capsys)
    assert status == 0, text + err
    rmap = load_map(out)
    assert rmap.provenance["device"] == "cpu" and rmap.shape == (4, 3)


def test_study_device_reaches_the_simulations_and_is_restored(tmp_path, capsys, monkeypatch):
    seen = []
    real = gpu.resolve_device

    def spy(device):
        seen.append((device, os.environ.get(gpu.DEVICE_VARIABLE)))
        return real(device)

    monkeypatch.setattr(gpu, "resolve_device", spy)
    monkeypatch.delenv(gpu.DEVICE_VARIABLE, raising=False)
    status, text, err = run(["study", "peak-force", "--grid", "2", "--workers", "1", "--device", "cpu",
                             "--out", str(tmp_path / "s")], capsys)
    assert status == 0, text + err
    assert seen[0] == ("cpu", None) and (None, "cpu") in seen  # the simulations read the default the command set
    assert gpu.DEVICE_VARIABLE not in os.environ
