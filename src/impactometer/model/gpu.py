"""GPU backend of the batch simulator: the fast integrator compiled for a CUDA device from the same source.

Nothing of the model is written twice. :func:`device_function` takes a compiled CPU function of the model (a numba
dispatcher such as :func:`.fast.integrate_into`), takes its Python source function (``py_func``) and compiles that
as a CUDA device function, after rebinding the compiled functions it calls -- directly or through a module of the
package (``d.rhs``) -- to their own device versions, recursively. The force laws, the right-hand side and the
Dormand-Prince 5(4) step with its error control are therefore the very functions the CPU batch runs; only the
kernel in :mod:`.gpu_kernel` (one thread per scenario, scratch arrays in thread-local memory) is specific
to the device.

Histories go back to the host a block of scenarios at a time, straight into the caller's array, while the device
integrates the next block; two blocks' device buffers stay within :data:`BLOCK_BYTES` (and half the free device
memory), so the number of scenarios is bounded by host memory only.

The optional dependency ``numba-cuda`` (extra ``impactometer[gpu]``) provides the CUDA target. With
``NUMBA_ENABLE_CUDASIM=1`` numba's CUDA simulator runs the same kernel as Python on the CPU (slowly): that is how
the GPU path is tested where no GPU exists.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import os
from collections.abc import Iterator

import numpy as np

from ..errors import DeviceError, ParameterError
from .gpu_source import device_function  # noqa: F401 - part of the GPU backend's API

#: name of the optional dependency set that brings the CUDA target
EXTRA = "impactometer[gpu]"
#: accepted values of ``device``
DEVICES = ("cpu", "gpu", "auto")
#: environment variable holding the default device of :func:`.simulate.simulate_batch` (``cpu`` when unset)
DEVICE_VARIABLE = "IMPACTOMETER_DEVICE"
#: threads per CUDA block (the kernel holds ~1.3 kB of scratch per thread in local memory)
THREADS_PER_BLOCK = 128
#: bound of the device memory one block of scenarios uses for its histories and parameters [bytes]
BLOCK_BYTES = 2 * 2**30


def simulator_enabled() -> bool:
    """True when numba's CUDA simulator is switched on (``NUMBA_ENABLE_CUDASIM=1``)."""
    return os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0")


@functools.cache
def unavailable_reason() -> str | None:
    """Why no GPU can be used in this process (None when one can, or when the CUDA simulator is on)."""
    if importlib.util.find_spec("numba_cuda") is None:
        return f"the package numba-cuda is not installed (install the extra: pip install '{EXTRA}')"
    try:
        from numba import cuda
    except Exception as exc:  # a numba-cuda release built against another numpy fails at import
        return (f"numba-cuda failed to import ({type(exc).__name__}: {exc}); install versions that match numpy "
                f"{np.__version__}: pip install '{EXTRA}'")
    if simulator_enabled():
        return None
    try:
        if cuda.is_available():
            return None
        error = cuda.cuda_error()
    except Exception as exc:
        error = exc
    text = " ".join(str(error).split()).rstrip(" :")  # the driver's message spans several lines
    return f"no usable CUDA GPU ({text or 'no device found'})"


def resolve_device(device: str | None) -> str:
    """``"cpu"`` or ``"gpu"`` for a requested ``device`` (None: the environment variable IMPACTOMETER_DEVICE, or
    ``"cpu"``).

    ``"auto"`` picks the GPU when one is usable (never the CUDA simulator), else the CPU. ``"gpu"`` without a
    usable GPU raises :class:`~impactometer.errors.DeviceError` naming the extra and the reason.
    """
    source = "device"
    if device is None:
        device, source = os.environ.get(DEVICE_VARIABLE, "cpu"), f"the environment variable {DEVICE_VARIABLE}"
    if not isinstance(device, str) or device.lower() not in DEVICES:
        raise ParameterError(f"{source} must be one of {list(DEVICES)}, got {device!r}")
    device = device.lower()
    if device == "cpu":
        return "cpu"
    reason = unavailable_reason()
    if device == "auto":
        return "gpu" if reason is None and not simulator_enabled() else "cpu"
    if reason is not None:
        raise DeviceError(f"device='gpu' needs the optional GPU support ({EXTRA}) and a CUDA GPU: {reason}")
    return "gpu"


@contextlib.contextmanager
def use_device(device: str) -> Iterator[None]:
    """Make ``device`` the default of :func:`.simulate.simulate_batch` inside the block, in this process and in
    the processes it starts (through the environment variable IMPACTOMETER_DEVICE)."""
    resolve_device(device)
    previous = os.environ.get(DEVICE_VARIABLE)
    os.environ[DEVICE_VARIABLE] = device
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(DEVICE_VARIABLE, None)
        else:
            os.environ[DEVICE_VARIABLE] = previous


def _block_size(n: int, bytes_per_scenario: int, block_bytes: int) -> int:
    budget = block_bytes
    if not simulator_enabled():
        from numba import cuda

        free, _ = cuda.current_context().get_memory_info()
        budget = min(budget, free // 2)
    size = max(1, budget // bytes_per_scenario)
    if size >= THREADS_PER_BLOCK:
        size -= size % THREADS_PER_BLOCK
    return min(n, size)


def integrate_batch(params, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, status, steps, *,
                    block_bytes: int = BLOCK_BYTES) -> None:
    """:func:`.fast.integrate_batch` on the GPU: the same arguments (host arrays), the same results.

    ``out`` (n, len(channel_index), len(t_out)), C-contiguous, may be float64 or float32; the device writes that
    type and each block is copied into its rows. Scenarios run a block at a time, two blocks' device buffers within
    ``block_bytes``.
    """
    try:
        _integrate_blocks(params, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, status, steps,
                          block_bytes)
    except Exception as exc:  # compilation (numba-cuda against an unsupported numpy), launch or device memory
        from importlib.metadata import PackageNotFoundError, version

        try:
            release = version("numba-cuda")
        except PackageNotFoundError:
            release = "(not found)"
        raise DeviceError(f"the GPU batch failed ({type(exc).__name__}: {exc}) with numba-cuda {release} and "
                          f"numpy {np.__version__}; where numba-cuda does not support "
                          f"this numpy, install the versions the extra pins: pip install '{EXTRA}'") from exc


def _integrate_blocks(params, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, status, steps,
                      block_bytes) -> None:
    """Two blocks in flight: the device integrates block k+1 on one stream while block k's histories are copied
    straight into ``out`` on another (no intermediate host array)."""
    from numba import cuda

    from .gpu_kernel import integrate as kernel

    n = params.shape[0]
    per_scenario = out[0].nbytes + 8 * (params.shape[1] + y0.shape[1] + 2)
    block = _block_size(n, per_scenario, block_bytes // 2)
    compute, transfer = cuda.stream(), cuda.stream()
    shared = (cuda.to_device(np.ascontiguousarray(t_out, dtype=np.float64), stream=compute),
              cuda.to_device(np.ascontiguousarray(channel_index, dtype=np.int64), stream=compute), float(rtol),
              cuda.to_device(np.ascontiguousarray(atol, dtype=np.float64), stream=compute), float(max_step),
              int(max_steps))
    in_flight = None
    for start in range(0, n, block):
        rows = slice(start, min(n, start + block))
        count = rows.stop - rows.start
        results = (cuda.device_array(out[rows].shape, dtype=out.dtype, stream=compute),
                   cuda.device_array(count, dtype=np.int64, stream=compute),
                   cuda.device_array(count, dtype=np.int64, stream=compute))
        grid = ((count + THREADS_PER_BLOCK - 1) // THREADS_PER_BLOCK, THREADS_PER_BLOCK, compute)
        kernel[grid](cuda.to_device(np.ascontiguousarray(params[rows]), stream=compute),
                     cuda.to_device(np.ascontiguousarray(y0[rows]), stream=compute), *shared, *results)
        done = cuda.event()
        done.record(compute)
        if in_flight is not None:
            _collect(*in_flight, transfer, out, status, steps)
        in_flight = (rows, results, done)
    if in_flight is not None:
        _collect(*in_flight, transfer, out, status, steps)


def _collect(rows, results, done, transfer, out, status, steps) -> None:
    """Copy one block's results into the host arrays once its kernel has finished."""
    done.wait(transfer)
    for device_array, host in zip(results, (out, status, steps), strict=True):
        device_array.copy_to_host(host[rows], stream=transfer)
    transfer.synchronize()
