"""Settings of the ``viz3d`` command's process, made before it imports numpy (``viz3d.__main__``);
imports nothing but the standard library."""

from __future__ import annotations

import gc
import os
import threading

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


#: How long the command's start-up holds the garbage collector at most [s] (``hold_collector``).
STARTUP_SECONDS = 1.0


def hold_collector(seconds: float = STARTUP_SECONDS) -> None:
    """Keep the cyclic garbage collector off for the command's start-up, at most ``seconds``; then
    freeze what was made so far (``gc.freeze``) and turn it on again (``release_collector``).

    A start-up creates some 10^5 objects that live as long as the process (numba's typing and
    lowering tables, viz3d's classes, the kernel loaded from the cache), and each full collection
    while they were made scanned all of them again: 30 ms of the 0.42 s a ``viz3d run`` of a small
    scene took (heavy_top, interleaved runs with and without, 2026-11-29). Frozen, the collections that follow skip
    them. The bound keeps a long command (a run, a viewer) collecting like any other process; cycles
    made and dropped within the start-up are kept (they are few, and the start-up ends). A process
    forked during the start-up (without the timer's thread) collects from its start."""
    if not gc.isenabled():
        return
    gc.disable()
    timer = threading.Timer(seconds, release_collector)
    timer.daemon = True
    timer.start()
    if hasattr(os, "register_at_fork"):
        os.register_at_fork(after_in_child=release_collector)


def release_collector() -> None:
    """End ``hold_collector``'s start-up: freeze the objects made so far and collect again (nothing if
    the collector is on)."""
    if not gc.isenabled():
        gc.freeze()
        gc.enable()
