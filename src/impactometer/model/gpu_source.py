"""One physics source, two targets: the CUDA device function compiled from a CPU-compiled (njit) function.

The GPU kernel (:mod:`.gpu_kernel`) is built from the very Python functions the CPU batch compiles, so the two can
not drift apart.
"""

from __future__ import annotations

import types
from typing import Any

from numba.core.dispatcher import Dispatcher

_DEVICE_FUNCTIONS: dict[int, Any] = {}
_DEVICE_MODULES: dict[str, types.ModuleType] = {}


def _device_module(module: types.ModuleType) -> types.ModuleType:
    """A stand-in for a module of the package whose compiled functions are device functions."""
    if module.__name__ not in _DEVICE_MODULES:
        proxy = types.ModuleType(module.__name__ + "[cuda]")
        _DEVICE_MODULES[module.__name__] = proxy
        for name, value in vars(module).items():
            setattr(proxy, name, device_function(value) if isinstance(value, Dispatcher) else value)
    return _DEVICE_MODULES[module.__name__]


def device_function(dispatcher: Dispatcher):
    """The CUDA device function compiled from the Python source of the CPU-compiled ``dispatcher``.

    The compiled functions it refers to, by name or as attributes of a module of the package, are replaced by
    their device functions, recursively; everything else (constants, tables, ``math``, ``numpy``) is shared.
    """
    from numba import cuda

    key = id(dispatcher)
    if key not in _DEVICE_FUNCTIONS:
        source = dispatcher.py_func
        namespace = dict(source.__globals__)
        for name in source.__code__.co_names:
            value = namespace.get(name)
            if isinstance(value, Dispatcher):
                namespace[name] = device_function(value)
            elif isinstance(value, types.ModuleType) and value.__name__.startswith(f"{__package__}."):
                namespace[name] = _device_module(value)
        function = types.FunctionType(source.__code__, namespace, source.__name__, source.__defaults__,
                                      source.__closure__)
        _DEVICE_FUNCTIONS[key] = cuda.jit(device=True)(function)
    return _DEVICE_FUNCTIONS[key]
