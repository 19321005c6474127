"""Interrupts that never cut a write in half.

Ctrl-C (SIGINT) and, under the command line, ``kill`` (SIGTERM) stop a run by raising
``KeyboardInterrupt`` wherever the main thread happens to be. Most places are fine; a few are not:
a recorder handing a buffer of frames to its file, a trajectory frame recorded but not yet sent to
the sinks, an archive half written. Inside ``InterruptGuard.held()`` such a signal is remembered and
delivered (to the handler it replaced) when the outermost held section ends, so the write completes.

Installing the guard costs two ``sigaction`` calls per run; a held section costs a counter
increment (a frame is handed to sinks every step when one asks for it, so swapping handlers there would
not do: about 12 us per swap).
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

SIGNALS = (signal.SIGINT, signal.SIGTERM)


class InterruptGuard:
    """Context manager: while entered, SIGINT and SIGTERM reach their usual handlers except
    inside ``held()`` sections, which receive them at their end.

    Only signals whose current handler is a Python callable are guarded (SIGINT's default raises
    ``KeyboardInterrupt``; SIGTERM is callable when the command line made it interrupt); a signal
    left at the operating system's default keeps it. Off the main thread (where signals cannot be
    set) the guard does nothing.
    """

    def __init__(self):
        self.depth = 0
        self.pending: tuple | None = None  # (signum, frame) received inside a held section
        self._previous: dict[int, object] = {}

    def __enter__(self) -> "InterruptGuard":
        if threading.current_thread() is threading.main_thread():
            for sig in SIGNALS:
                if callable(signal.getsignal(sig)):
                    self._previous[sig] = signal.signal(sig, self._receive)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def _receive(self, signum, frame) -> None:
        if self.depth:
            self.pending = self.pending or (signum, frame)
        else:
            self._previous[signum](signum, frame)

    @contextmanager
    def held(self, deliver: bool = True):
        """A section no interrupt cuts: one received inside is delivered when the outermost held
        section ends (``deliver=False``: kept pending instead, for a section that ends the run
        anyway; ``pending`` tells the caller)."""
        self.depth += 1
        try:
            yield
        finally:
            self.depth -= 1
            if deliver and not self.depth and self.pending is not None:
                (signum, frame), self.pending = self.pending, None
                self._previous[signum](signum, frame)
