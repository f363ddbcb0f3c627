"""The CUDA kernel of the GPU batch: one thread integrates one scenario with :func:`.fast.integrate_into`.

Imported only once :mod:`.gpu` has found the CUDA target usable (it needs the optional ``numba-cuda``).
"""

from __future__ import annotations

from numba import cuda, float64, int64

from . import dynamics as d
from . import fast
from .gpu_source import device_function

ROWS, N_STATE, N_CHANNEL = fast.WORK_ROWS, d.N_STATE, d.N_CHANNEL
integrate_into = device_function(fast.integrate_into)


@cuda.jit
def integrate(params, y0, t_out, channel_index, rtol, atol, max_step, max_steps, out, status, steps):
    """Scenario ``cuda.grid(1)`` of the block: :func:`.fast.integrate_into` with thread-local scratch arrays."""
    s = cuda.grid(1)
    if s < params.shape[0]:
        work = cuda.local.array((ROWS, N_STATE), float64)
        need = cuda.local.array(N_STATE, int64)
        row = cuda.local.array(N_CHANNEL, float64)
        status[s], steps[s] = integrate_into(params[s], y0[s], t_out, channel_index, rtol, atol, max_step,
                                             max_steps, out[s], work, need, row)
