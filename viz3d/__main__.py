"""``python -m viz3d`` is the ``viz3d`` command (``command``, the console script's entry point too)."""

import gc
import os
import sys

from viz3d.process import hold_collector, single_threaded_blas

single_threaded_blas()
hold_collector()

from viz3d.cli import RECEIVED, main  # noqa: E402  (after the BLAS threads are chosen)


def command() -> int:
    """Run the command line and return its exit code, the process about to end.

    Freezes the garbage collector's objects first: the interpreter's shutdown then does not scan
    the 10^5 objects of numba's compiler again and again (0.25-0.3 s of a 1 s ``viz3d run``,
    benchmarks/bench_startup.py). Objects are still released as the modules go; only cycles among
    them are left to the operating system. Not in ``cli.main``, which tests call many times in one
    process.
    """
    code = main()
    gc.freeze()
    if RECEIVED:
        _exit_now(code)
    return code


def _exit_now(code: int) -> None:
    """End the process with ``code`` now that the command has finished (its files written and
    closed). After a SIGTERM the interpreter's normal exit sometimes ended the process with SIGINT
    instead (exit status -2 in 3-9 of 30 ``kill``-ed runs of heavy_top; 0 of 30 with this):
    CPython keeps a flag once a ``KeyboardInterrupt`` has crossed some of its C-level entry points
    and re-raises SIGINT on itself at exit, although ``cli.main`` caught the interrupt.
    ``os._exit`` after flushing keeps the code."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    raise SystemExit(command())
