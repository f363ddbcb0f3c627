"""Compile the GPU batch kernel for a CUDA architecture on a machine without a GPU, and report its resources.

numba's CUDA simulator runs the kernel's Python source and so cannot tell whether the model compiles for a real
device. This script compiles :mod:`impactometer.model.gpu_kernel` to PTX with NVVM (no driver, no GPU needed) for
float64 and float32 histories and, where ``ptxas`` is found, assembles it and prints the registers, stack and
spills per thread.

    pip install "impactometer[gpu]"          # numba-cuda with NVVM and NVRTC (CUDA 12 libraries)
    python scripts/gpu_compile_check.py --cc 9.0 [--ptxas PATH]

numba-cuda asks the current device for its compute capability when it compiles a device function that a kernel
calls; without a driver that fails, so this script (and only this script) answers with ``--cc`` instead.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cc", default="9.0", help="compute capability MAJOR.MINOR (9.0: H100)")
    parser.add_argument("--ptxas", default=shutil.which("ptxas"), help="ptxas to assemble the PTX with")
    args = parser.parse_args()
    cc = tuple(int(part) for part in args.cc.split("."))

    import numba.cuda.dispatcher as dispatcher
    from numba import cuda, float32, float64, int64, void

    class _Device:
        compute_capability = cc

    dispatcher.get_current_device = lambda: _Device()  # type: ignore[attr-defined]
    from impactometer.model import gpu_kernel

    for out_type in (float64, float32):
        signature = void(float64[:, ::1], float64[:, ::1], float64[::1], int64[::1], float64, float64[::1], float64,
                         int64, out_type[:, :, ::1], int64[::1], int64[::1])
        start = time.perf_counter()
        ptx, _ = cuda.compile_ptx(gpu_kernel.integrate.py_func, signature, cc=cc)
        print(f"histories {out_type}: PTX for sm_{cc[0]}{cc[1]}, {len(ptx):,} characters, "
              f"{time.perf_counter() - start:.1f} s")
        if args.ptxas:
            with tempfile.TemporaryDirectory() as folder:
                source = Path(folder) / "kernel.ptx"
                source.write_text(ptx)
                done = subprocess.run([args.ptxas, f"-arch=sm_{cc[0]}{cc[1]}", "-v", str(source), "-o",
                                       str(Path(folder) / "kernel.cubin")], capture_output=True, text=True)
            lines = done.stderr.splitlines()
            used = [i for i, line in enumerate(lines) if "Used" in line]  # the kernel's: its spills come before
            summary = " | ".join(lines[i].split("info    :")[-1].strip() for j in used for i in (j - 1, j))
            print("  ptxas: " + (summary if done.returncode == 0 else done.stderr.strip()))


if __name__ == "__main__":
    main()
