"""``python -m viz3d`` is the ``viz3d`` command (``command``, the console script's entry point too)."""

import gc

from viz3d.cli import main


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
    return code


if __name__ == "__main__":
    raise SystemExit(command())
