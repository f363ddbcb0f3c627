"""Speed of the compiled batch integrator against scipy ``solve_ivp``, and its agreement with the reference.

Run: ``python benchmarks/bench_simulate.py`` (add ``--skip-agreement`` to leave out the 125-case grid check).
``python benchmarks/bench_simulate.py --device gpu`` instead compares the GPU batch with the CPU batch (needs a CUDA
GPU and the extra ``impactometer[gpu]``): scenarios/s of each, their ratio, and their agreement on the 125 cases.

In one process it
1. simulates a batch of drop tests (50 ms, 50 kHz, contact force + piston acceleration) with the fast integrator;
2. simulates a sample of the same scenarios with ``solve_ivp(method="RK45")`` -- the same Dormand-Prince 5(4) pair,
   the same rtol/atol/max_step -- once with the model's right-hand side as plain Python (every compiled function
   replaced by its ``py_func``, recursively) and once with the compiled right-hand side; the solve_ivp timings
   leave out computing the output channels from the states, which favours solve_ivp;
3. checks that both reach the same accuracy (contact-force peaks against a DOP853 rtol 1e-12 solution);
4. reports the fast batch's throughput and peak memory for 10 000 scenarios;
5. measures the fast-vs-reference agreement on the paper's 125-case grid for both contact laws.
"""

from __future__ import annotations

import argparse
import os
import resource
import time
import tracemalloc
import types

import numba
import numpy as np
from numba.core.registry import CPUDispatcher
from scipy.integrate import solve_ivp

from impactometer.model import dynamics as d
from impactometer.model import reference, simulate_batch
from impactometer.model.setup import initial_states
from impactometer.model.simulate import DEFAULT_RTOL, MAX_STEP, MAX_STEPS, absolute_tolerance, compare_integrators
from impactometer.rig import CONTACT_LAWS, get_rig
from recorded import recorded

DURATION, SAMPLE_RATE = 0.05, 50e3


_PLAIN: dict = {}  # dispatcher -> its plain-Python function, built once


def plain_python(function):
    """``function`` (a numba dispatcher) as plain Python, with every compiled function it calls replaced too."""
    _memo = _PLAIN
    if function not in _memo:
        source = function.py_func
        namespace = dict(source.__globals__)
        for name in source.__code__.co_names:
            if isinstance(namespace.get(name), CPUDispatcher):
                namespace[name] = plain_python(namespace[name])
        _memo[function] = types.FunctionType(source.__code__, namespace, source.__name__, source.__defaults__,
                                             source.__closure__)
    return _memo[function]


def scenarios(n, seed=1):
    """Random scenarios over the paper's ranges: M1 10-50 kg, V0 1-3 m/s, p0 20-400 kPa."""
    rng = np.random.default_rng(seed)
    return rng.uniform(10, 50, n), rng.uniform(1, 3, n), rng.uniform(20e3, 400e3, n)


def time_fast(mass, velocity, pressure, rig, rtol, repeat=3):
    """Best wall time and best CPU time (all threads) [s] of ``simulate_batch`` over ``repeat`` runs, and the
    last result."""
    best, best_cpu = np.inf, np.inf
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        batch = simulate_batch(mass, velocity, pressure, rig, duration=DURATION, sample_rate=SAMPLE_RATE,
                               rtol=rtol)
        best, best_cpu = min(best, time.perf_counter() - start), min(best_cpu, time.process_time() - start_cpu)
    return best, best_cpu, batch


def time_solve_ivp(params, rhs, rtol, t_eval, method="RK45"):
    """Wall and CPU time [s] of solve_ivp over every parameter row with right-hand side ``rhs``, and the force
    histories."""
    atol = absolute_tolerance(rtol)
    solutions = []
    start, start_cpu = time.perf_counter(), time.process_time()
    for p, y0 in zip(params, initial_states(params), strict=False):
        valve = float(p[d.VALVE_AREA])

        def fun(_t, y, p=p, valve=valve):
            dy = np.empty_like(y)
            rhs(y, p, valve, dy)
            return dy

        solutions.append(solve_ivp(fun, (0.0, t_eval[-1]), y0, method=method, t_eval=t_eval, rtol=rtol, atol=atol,
                                   max_step=MAX_STEP))
    elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
    force = d.CHANNELS.index("contact_force")
    forces = np.array([reference.channels_of(sol.y, p, t_eval)[force] if sol.status == 0
                       else np.full(t_eval.size, np.nan) for sol, p in zip(solutions, params, strict=False)])
    return elapsed, cpu, forces


def peak_error(forces, exact):
    return float(np.max(np.abs(forces.max(axis=1) / exact.max(axis=1) - 1.0)))


def speed(n_fast, n_scipy, rtol, rec):
    rig = get_rig()
    mass, velocity, pressure = scenarios(n_fast)
    simulate_batch(mass[:2], velocity[:2], pressure[:2], rig, duration=DURATION, sample_rate=SAMPLE_RATE)  # compile
    fast_time, fast_cpu, batch = time_fast(mass, velocity, pressure, rig, rtol)
    params = batch.params[:n_scipy]
    t_eval = batch.time
    python = time_solve_ivp(params, plain_python(d.rhs), rtol, t_eval)
    compiled = time_solve_ivp(params, d.rhs, rtol, t_eval)
    exact = time_solve_ivp(params, d.rhs, 1e-12, t_eval, method="DOP853")[2]
    fast_rate, fast_cpu_rate = n_fast / fast_time, n_fast / fast_cpu
    print(f"\n## Speed: {DURATION * 1e3:g} ms at {SAMPLE_RATE / 1e3:g} kHz, rtol {rtol:g} (atol = rtol x state scale), "
          f"max_step {MAX_STEP:g} s, {numba.get_num_threads()} threads, load average {os.getloadavg()[0]:.1f}")
    print("| integrator | scenarios | wall [s] | scenarios/s (wall) | fast / this (wall) | scenarios per CPU-s | "
          "fast / this (CPU) | peak-force error vs DOP853 1e-12 |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    fast_error = peak_error(batch["contact_force"][:n_scipy], exact)
    print(f"| fast batch (numba, parallel) | {n_fast} | {fast_time:.3f} | {fast_rate:,.0f} | 1 | {fast_cpu_rate:,.0f} "
          f"| 1 | {fast_error:.1e} |")
    for name, (elapsed, cpu, forces) in (("solve_ivp RK45 + plain-Python rhs", python),
                                         ("solve_ivp RK45 + compiled rhs", compiled)):
        rate, cpu_rate = n_scipy / elapsed, n_scipy / cpu
        print(f"| {name} | {n_scipy} | {elapsed:.3f} | {rate:,.1f} | {fast_rate / rate:,.0f} | {cpu_rate:,.1f} | "
              f"{fast_cpu_rate / cpu_rate:,.0f} | {peak_error(forces, exact):.1e} |")
        if "plain-Python" in name and rtol == DEFAULT_RTOL["fast"]:
            rec.headline(f"simulation: fast batch / solve_ivp RK45 (rtol {rtol:g}, wall)",
                         f"{fast_rate / rate:,.0f}× ({fast_rate:,.0f} scenarios/s)", target="1000×")
    print(f"\nmean accepted steps per scenario (fast): {batch.steps.mean():.0f}")


def throughput(n, dtype):
    rig = get_rig()
    mass, velocity, pressure = scenarios(n, seed=2)
    tracemalloc.start()
    start = time.perf_counter()
    batch = simulate_batch(mass, velocity, pressure, rig, duration=DURATION, sample_rate=SAMPLE_RATE, dtype=dtype)
    elapsed = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    histories = sum(a.nbytes for a in batch.data.values())
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"| {n} | {np.dtype(dtype).name} | {elapsed:.2f} | {n / elapsed:,.0f} | {histories / 2**20:,.0f} | "
          f"{peak / 2**20:,.0f} | {rss:,.0f} |")


def agreement():
    grid = np.meshgrid([10.0, 20.0, 30.0, 40.0, 50.0], [1.0, 1.5, 2.0, 2.5, 3.0],
                       [20e3, 115e3, 210e3, 305e3, 400e3], indexing="ij")
    print(f"\n## Fast (rtol {DEFAULT_RTOL['fast']:g} unless stated) vs reference (DOP853, rtol "
          f"{DEFAULT_RTOL['reference']:g}), 125 scenarios, 50 ms at 200 kHz")
    print("| stand | contact law | fast rtol | pulses compared | max rel. diff. peak force | max rel. diff. impulse | "
          "max diff. pulse-peak time [µs] | pulse-count mismatches |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    # the pad's sustained-contact maxima are flat: their times converge with the fast rtol (second hysteretic row)
    for stand, law, rtol in (("drop-stand", "kelvin-voigt", None), ("drop-stand", "hunt-crossley", None),
                             ("drop-stand", "hysteretic", None), ("drop-stand", "hysteretic", 1e-10),
                             ("drop-stand-stiff", "kelvin-voigt", None)):
        a = compare_integrators(*grid, get_rig(stand, contact=law), duration=0.05, sample_rate=200e3, rtol=rtol)
        print(f"| {stand} | {law} | {rtol or DEFAULT_RTOL['fast']:g} | {a.pulses} | {a.peak_force:.1e} | "
              f"{a.impulse:.1e} | {a.peak_time * 1e6:.3f} | {a.pulse_count_mismatches} |")


def gpu_versus_cpu(n_gpu, n_cpu, agree=True, repeat=3):
    """Scenarios/s of the GPU and the CPU batch on the same kind of scenarios, their ratio and their agreement.

    Histories come back a block at a time (``simulate_blocks``) and each block is dropped, so 10^6 scenarios need
    one block's memory.
    """
    from numba import cuda

    from impactometer.model.simulate import compare_devices, simulate_blocks

    rig = get_rig()
    mass, velocity, pressure = scenarios(max(n_gpu, n_cpu), seed=3)
    options = {"duration": DURATION, "sample_rate": SAMPLE_RATE}
    rates = {}
    for device, n, dtype in (("gpu", n_gpu, np.float64), ("gpu", n_gpu, np.float32), ("cpu", n_cpu, np.float64)):
        simulate_batch(mass[:2], velocity[:2], pressure[:2], rig, device=device, dtype=dtype, **options)  # compile
        best = np.inf
        for _ in range(repeat):
            start = time.perf_counter()
            steps = sum(float(block.steps.sum()) for _, block in
                        simulate_blocks(mass[:n], velocity[:n], pressure[:n], rig, device=device, dtype=dtype,
                                        **options))
            best = min(best, time.perf_counter() - start)
        rates[device, np.dtype(dtype).name] = (n, best, n / best, steps / n)
    name = getattr(cuda.get_current_device(), "name", "CUDA simulator")
    name = name.decode() if isinstance(name, bytes) else name
    print(f"\n## GPU vs CPU batch: {DURATION * 1e3:g} ms at {SAMPLE_RATE / 1e3:g} kHz, contact force + piston "
          f"acceleration histories copied back to the host, rtol {DEFAULT_RTOL['fast']:g}; GPU: {name}; CPU: "
          f"{numba.get_num_threads()} threads, load average {os.getloadavg()[0]:.1f}")
    print("| device | histories dtype | scenarios | wall [s] | scenarios/s | mean accepted steps |")
    print("|---|---|---:|---:|---:|---:|")
    for (device, dtype), (n, wall, rate, steps) in rates.items():
        print(f"| {device} | {dtype} | {n} | {wall:.3f} | {rate:,.0f} | {steps:.0f} |")
    cpu = rates["cpu", "float64"][2]
    print(f"\nGPU / CPU throughput: {rates['gpu', 'float64'][2] / cpu:,.1f} (float64 histories), "
          f"{rates['gpu', 'float32'][2] / cpu:,.1f} (float32 on the GPU)")
    kernel_only(name, n_gpu, cpu)
    if not agree:
        return
    grid = np.meshgrid([10.0, 20.0, 30.0, 40.0, 50.0], [1.0, 1.5, 2.0, 2.5, 3.0],
                       [20e3, 115e3, 210e3, 305e3, 400e3], indexing="ij")
    print("\n## GPU vs CPU batch, 125 scenarios, 50 ms at 200 kHz")
    print("| contact law | pulses compared | max rel. diff. peak force | max rel. diff. impulse | "
          "max diff. pulse-peak time [µs] | pulse-count mismatches |")
    print("|---|---:|---:|---:|---:|---:|")
    for law in CONTACT_LAWS:  # every shipped law
        a = compare_devices(*grid, get_rig(contact=law), duration=0.05, sample_rate=200e3)
        print(f"| {law} | {a.pulses} | {a.peak_force:.1e} | {a.impulse:.1e} | {a.peak_time * 1e6:.3f} | "
              f"{a.pulse_count_mismatches} |")


def kernel_only(name, n, cpu_rate, block=65536):
    """Scenarios/s of the GPU kernel alone (histories left on the device, as a reduction on the device would), the
    bound that copying histories back to the host falls short of."""
    from numba import cuda

    from impactometer.model import gpu
    from impactometer.model.gpu_kernel import integrate as kernel

    block = min(n, block)
    # the packed parameters of the same kind of scenarios, from the CPU batch (one narrow channel to save memory)
    batch = simulate_batch(*scenarios(block, seed=3), duration=DURATION, sample_rate=SAMPLE_RATE, channels=("a2",),
                           dtype=np.float32, device="cpu")
    params = batch.params
    rtol = DEFAULT_RTOL["fast"]
    index = np.array([d.CHANNELS.index("contact_force"), d.CHANNELS.index("a2")])
    args = [cuda.to_device(a) for a in (params, initial_states(params), batch.time, index)]
    out = cuda.device_array((block, 2, batch.time.size))
    status, steps = cuda.device_array(block, np.int64), cuda.device_array(block, np.int64)
    grid = ((block + gpu.THREADS_PER_BLOCK - 1) // gpu.THREADS_PER_BLOCK, gpu.THREADS_PER_BLOCK)
    best = np.inf
    for _ in range(4):
        start = time.perf_counter()
        kernel[grid](args[0], args[1], args[2], args[3], rtol, cuda.to_device(absolute_tolerance(rtol)), MAX_STEP,
                     MAX_STEPS, out, status, steps)
        cuda.synchronize()
        best = min(best, time.perf_counter() - start)
    print(f"GPU kernel alone ({name}, {block} scenarios, histories left on the device): {block / best:,.0f} "
          f"scenarios/s, {block / best / cpu_rate:,.1f} x the CPU batch")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "gpu"), default="cpu",
                        help="gpu: compare the GPU batch with the CPU batch instead")
    parser.add_argument("--gpu-scenarios", type=int, default=1_000_000)
    parser.add_argument("--fast-scenarios", type=int, default=2000)
    parser.add_argument("--scipy-scenarios", type=int, default=20)
    parser.add_argument("--throughput-scenarios", type=int, default=10_000)
    parser.add_argument("--skip-agreement", action="store_true")
    parser.add_argument("--record", action="store_true", help="keep the output in docs/results/ and the docs")
    args = parser.parse_args()
    if args.device == "gpu":
        from impactometer.errors import DeviceError
        from impactometer.model.gpu import resolve_device

        try:
            resolve_device("gpu")
        except DeviceError as exc:
            raise SystemExit(f"--device gpu: {exc}") from None
        with recorded("bench_simulate_gpu", "Simulation: GPU batch against the CPU batch", args.record):
            gpu_versus_cpu(args.gpu_scenarios, args.fast_scenarios, agree=not args.skip_agreement)
        return
    with recorded("bench_simulate", "Simulation: fast integrator against solve_ivp, agreement with the reference",
                  args.record) as rec:
        for rtol in (DEFAULT_RTOL["fast"], 1e-8):
            speed(args.fast_scenarios, args.scipy_scenarios, rtol, rec)
        print(f"\n## Throughput and memory (rtol {DEFAULT_RTOL['fast']:g}, contact force + piston acceleration)")
        print("| scenarios | histories dtype | wall time [s] | scenarios/s | histories [MiB] | "
              "tracemalloc peak [MiB] | process peak RSS [MiB] |")
        print("|---:|---|---:|---:|---:|---:|---:|")
        for dtype in (np.float32, np.float64):
            throughput(args.throughput_scenarios, dtype)
        if not args.skip_agreement:
            agreement()

if __name__ == "__main__":
    main()
