"""GPU batch: the same model source on a CUDA device (numba's CUDA simulator here, a real GPU where one exists),
device selection and its errors, and the block-wise batch."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from impactometer.errors import DeviceError, ImpactometerError, ParameterError
from impactometer.model import gpu, simulate_batch
from impactometer.model.simulate import compare_devices, simulate_blocks
from impactometer.rig import get_rig

LAWS = ("kelvin-voigt", "hunt-crossley", "hysteretic", "power")
#: the paper's 125-case grid (M1 × V0 × p0)
GRID = np.meshgrid([10.0, 20.0, 30.0, 40.0, 50.0], [1.0, 1.5, 2.0, 2.5, 3.0], [20e3, 115e3, 210e3, 305e3, 400e3],
                   indexing="ij")
#: agreement demanded of the GPU batch against the CPU batch
PEAK_FORCE, IMPULSE, PEAK_TIME = 1e-4, 1e-4, 1e-6

NUMBA_CUDA = importlib.util.find_spec("numba_cuda") is not None

# run under NUMBA_ENABLE_CUDASIM=1 in a child process: the simulator is chosen when numba.cuda is first imported
_SIMULATED = textwrap.dedent("""
    import json
    import numpy as np
    from impactometer.model import gpu
    from impactometer.model.setup import initial_states
    from impactometer.model.simulate import absolute_tolerance, compare_devices, simulate_batch
    from impactometer.rig import get_rig

    # corners and centre of the 125-case grid: light/fast/soft, heavy/slow/stiff, ...
    mass = np.array([10.0, 50.0, 30.0, 50.0])
    velocity = np.array([3.0, 1.0, 2.0, 3.0])
    pressure = np.array([20e3, 400e3, 210e3, 20e3])
    report = {}
    # 20 ms at 100 kHz: the first two contacts and the start of stage B, 7-9 pulses per law (the simulator interprets
    # the kernels in Python: 50 ms at 200 kHz took about 8 minutes; the real-GPU test below runs those on 125 cases)
    for law in ("kelvin-voigt", "hunt-crossley", "hysteretic", "power"):
        a = compare_devices(mass, velocity, pressure, get_rig(contact=law), duration=0.02, sample_rate=100e3)
        report[law] = {"peak_force": a.peak_force, "impulse": a.impulse, "peak_time": a.peak_time,
                       "mismatches": a.pulse_count_mismatches, "pulses": a.pulses}
    # several device blocks (a budget of one scenario's buffers) and float32 histories written on the device
    cpu = simulate_batch(mass, velocity, pressure, duration=0.01, sample_rate=50e3, channels=("u1", "a2"),
                         device="cpu")
    t, params = cpu.time, cpu.params
    out = np.empty((4, 2, t.size), dtype=np.float32)
    status, steps = np.full(4, -1), np.zeros(4, dtype=np.int64)
    gpu.integrate_batch(params, initial_states(params), t, np.array([0, 11]), 1e-9, absolute_tolerance(1e-9),
                        1e-3, 10**7, out, status, steps, block_bytes=out[0].nbytes)
    report["blocks"] = {"status": status.tolist(), "steps_equal": bool(np.array_equal(steps, cpu.steps)),
                        "u1": float(np.max(np.abs(out[:, 0] - cpu["u1"]) / np.max(np.abs(cpu["u1"])))),
                        "a2": float(np.max(np.abs(out[:, 1] - cpu["a2"]) / np.max(np.abs(cpu["a2"]))))}
    print(json.dumps(report))
""")


@pytest.fixture
def fresh_reason():
    """Forget the cached GPU probe before and after a test that fakes the environment."""
    gpu.unavailable_reason.cache_clear()
    yield
    gpu.unavailable_reason.cache_clear()


@pytest.mark.slow
@pytest.mark.skipif(not NUMBA_CUDA, reason="numba-cuda is not installed (it comes with the 'test' and 'gpu' "
                                            "extras): the CUDA simulator needs it")
def test_cuda_simulator_runs_the_same_model_as_the_cpu_batch():
    env = {**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}
    done = subprocess.run([sys.executable, "-c", _SIMULATED], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    for law in LAWS:
        r = report[law]
        assert r["pulses"] >= 4 and r["mismatches"] == 0, (law, r)
        assert r["peak_force"] <= PEAK_FORCE and r["impulse"] <= IMPULSE and r["peak_time"] <= PEAK_TIME, (law, r)
    blocks = report["blocks"]
    assert blocks["status"] == [0, 0, 0, 0] and blocks["steps_equal"]
    assert blocks["u1"] <= 1e-7 and blocks["a2"] <= 1e-7  # float32 storage (2^-24 relative) of the same histories


@pytest.mark.skipif(not NUMBA_CUDA, reason="numba-cuda is not installed (it comes with the 'test' and 'gpu' "
                                            "extras)")
def test_device_functions_are_compiled_from_the_cpu_functions_code():
    from numba.core.dispatcher import Dispatcher

    from impactometer.model import dynamics, fast, forces

    step = gpu.device_function(fast.integrate_into)
    assert step.py_func.__code__ is fast.integrate_into.py_func.__code__  # the same code object, not a copy
    module = step.py_func.__globals__["d"]  # the dynamics module, its compiled functions as device functions
    assert module.rhs is gpu.device_function(dynamics.rhs)
    assert module.rhs.py_func.__code__ is dynamics.rhs.py_func.__code__
    law = module.rhs.py_func.__globals__["contact_force"]
    assert law.py_func.__code__ is forces.contact_force.py_func.__code__
    assert module.N_STATE == dynamics.N_STATE and step.py_func.__globals__["_P"] is fast._P
    # nothing compiled for the CPU is left for the device code to call
    for function in (step, module.rhs, law):
        names = function.py_func.__code__.co_names
        assert not any(isinstance(function.py_func.__globals__.get(n), Dispatcher) for n in names)


def _flat_maxima_miss(law):
    return pytest.param(law, None, marks=pytest.mark.xfail(
        strict=True, reason="known miss at the default rtol 1e-9 (measured on an H200: 2.5 µs hysteretic, 1.3 µs "
        "power): the flat maxima of these pads' sustained contact move with rounding, while peak force and impulse "
        "agree to 1.5e-6; as between the CPU fast and reference integrators, they are compared at rtol 1e-10"))


@pytest.mark.slow
@pytest.mark.parametrize("law, rtol", [("kelvin-voigt", None), ("hunt-crossley", None),
                                       _flat_maxima_miss("hysteretic"), ("hysteretic", 1e-10),
                                       _flat_maxima_miss("power"), ("power", 1e-10)])
def test_real_gpu_agrees_with_the_cpu_batch_on_the_125_cases(law, rtol):
    reason = gpu.unavailable_reason()
    if reason is not None or gpu.simulator_enabled():
        pytest.skip(f"needs a usable CUDA GPU: {reason or 'the CUDA simulator is on'}")
    a = compare_devices(*GRID, get_rig(contact=law), duration=0.05, sample_rate=200e3, rtol=rtol)
    assert a.pulse_count_mismatches == 0 and a.pulses >= 125
    assert a.peak_force <= PEAK_FORCE and a.impulse <= IMPULSE and a.peak_time <= PEAK_TIME, a


def test_gpu_request_without_a_usable_gpu_names_the_extra_and_the_reason(monkeypatch):
    monkeypatch.setattr(gpu, "unavailable_reason", lambda: "no usable CUDA GPU (no device found)")
    with pytest.raises(DeviceError, match=r"impactometer\[gpu\].*no usable CUDA GPU \(no device found\)"):
        simulate_batch(20.0, 2.0, 200e3, duration=0.005, device="gpu")
    assert issubclass(DeviceError, ImpactometerError) and issubclass(DeviceError, RuntimeError)
    # auto falls back to the CPU and gives the CPU's answer
    auto = simulate_batch(20.0, 2.0, 200e3, duration=0.005, device="auto")
    cpu = simulate_batch(20.0, 2.0, 200e3, duration=0.005, device="cpu")
    assert np.array_equal(auto["contact_force"], cpu["contact_force"])


def test_missing_numba_cuda_is_reported_with_the_extra(monkeypatch, fresh_reason):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "numba_cuda" else real(name, *a))
    assert "numba-cuda is not installed" in gpu.unavailable_reason()
    with pytest.raises(DeviceError, match=r"pip install 'impactometer\[gpu\]'"):
        gpu.resolve_device("gpu")
    assert gpu.resolve_device("auto") == "cpu"


def test_numba_cuda_that_fails_to_import_is_reported_with_the_numpy_version(monkeypatch, fresh_reason):
    import numba

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: object() if name == "numba_cuda" else real(name, *a))
    monkeypatch.delattr(numba, "cuda", raising=False)
    monkeypatch.setitem(sys.modules, "numba.cuda", None)
    reason = gpu.unavailable_reason()
    assert "failed to import" in reason and np.__version__ in reason and "impactometer[gpu]" in reason


def test_a_failing_device_run_becomes_a_device_error(monkeypatch):
    def incompatible(*args):
        raise AttributeError("module 'numpy' has no attribute 'row_stack'")

    monkeypatch.setattr(gpu, "_integrate_blocks", incompatible)
    with pytest.raises(DeviceError, match=rf"row_stack.*numpy {np.__version__}.*impactometer\[gpu\]"):
        gpu.integrate_batch(*(None,) * 11)


@pytest.mark.parametrize("device", ["tpu", "", 1, "cuda"])
def test_unknown_device_is_a_parameter_error(device):
    with pytest.raises(ParameterError, match=r"device must be one of \['cpu', 'gpu', 'auto'\]"):
        simulate_batch(20.0, 2.0, 200e3, duration=0.005, device=device)


def test_default_device_comes_from_the_environment(monkeypatch):
    monkeypatch.setenv(gpu.DEVICE_VARIABLE, "CPU")
    assert gpu.resolve_device(None) == "cpu"
    monkeypatch.setenv(gpu.DEVICE_VARIABLE, "fpga")
    with pytest.raises(ParameterError, match="IMPACTOMETER_DEVICE must be one of"):
        simulate_batch(20.0, 2.0, 200e3, duration=0.005)
    monkeypatch.delenv(gpu.DEVICE_VARIABLE)
    assert gpu.resolve_device(None) == "cpu"


def test_blocks_cover_the_batch_in_order_with_the_same_histories():
    mass, velocity = np.meshgrid([10.0, 30.0, 50.0], [1.0, 3.0], indexing="ij")
    whole = simulate_batch(mass, velocity, 200e3, duration=0.01, channels=("contact_force", "u2"))
    blocks = list(simulate_blocks(mass, velocity, 200e3, duration=0.01, channels=("contact_force", "u2"),
                                  block_size=4))
    assert [rows for rows, _ in blocks] == [slice(0, 4), slice(4, 6)]
    for name in ("contact_force", "u2"):
        assert np.array_equal(np.concatenate([b[name] for _, b in blocks]), whole[name])
    assert np.array_equal(np.concatenate([b.mass for _, b in blocks]), whole.mass)


@pytest.mark.parametrize("block_size", [0, -3, 2.5, True])
def test_bad_block_size_is_a_parameter_error(block_size):
    with pytest.raises(ParameterError, match="block_size must be an integer >= 1"):
        next(simulate_blocks(20.0, 2.0, 200e3, duration=0.005, block_size=block_size))


def test_blocks_check_every_scenario_before_simulating():
    with pytest.raises(ParameterError, match=r"mass\[1\] must be a finite number > 0"):
        next(simulate_blocks([20.0, -1.0], 2.0, 200e3, duration=0.005, block_size=1))
