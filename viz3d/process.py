"""Settings of the ``viz3d`` command's process, made before it imports numpy (``viz3d.__main__``);
imports nothing but the standard library."""

from __future__ import annotations

import os

#: The environment variables OpenBLAS takes its thread count from (the first set wins).
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")


def single_threaded_blas(environ=os.environ) -> None:
    """Run the command's BLAS (numpy's and scipy's OpenBLAS) on one thread unless the user chose a
    count (``BLAS_THREADS``); set before numpy is imported, which starts the thread pool.

    viz3d's matrices are small (the kernel calls no BLAS; the NumPy path's blocks and bands are tens
    to hundreds of rows), a study's parallelism is its worker processes, and starting OpenBLAS's pool
    took 0.05 s of ``import numpy`` on this 2-core machine (0.17-0.24 s against 0.11-0.17 s wall).
    With another job on the cores a pool of two was far slower still: a 300 x 300 LU and product
    took 0.22 s against 1.7 ms on one thread (load 3)."""
    if not any(environ.get(name) for name in BLAS_THREADS):
        environ["OPENBLAS_NUM_THREADS"] = "1"
