"""The ``Sink`` protocol: everything that consumes a run (viewer, recorder, tests).

A run calls ``open(visuals)`` once, ``log(frame)`` for each frame it produces, ``event(t, text)``
for discrete events (contact start/end, the final status), and ``close()`` exactly once, also
after a failure or Ctrl-C. A sink with ``full_rate = True`` receives a frame after every
integration step; otherwise only at the run's output interval.
"""

from __future__ import annotations

from typing import Protocol

from viz3d.frames import Frame, SceneVisuals


class Sink(Protocol):
    full_rate: bool

    def open(self, visuals: SceneVisuals) -> None: ...

    def log(self, frame: Frame) -> None: ...

    def event(self, t: float, text: str, level: str = "info") -> None: ...

    def close(self) -> None: ...


class NullSink:
    """Accepts and discards everything."""

    full_rate = False

    def open(self, visuals):
        pass

    def log(self, frame):
        pass

    def event(self, t, text, level="info"):
        pass

    def close(self):
        pass
