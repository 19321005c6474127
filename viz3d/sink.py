"""The ``Sink`` protocol: everything that consumes a run (viewer, recorder, tests).

A run calls ``open(visuals)`` once, ``log(frame)`` for each frame it produces, ``event(t, text)``
for discrete events (contact start/end, the final status), and ``close()`` exactly once, also
after a failure or Ctrl-C. Frames and events arrive in time order.

Which frames: a sink gets the frame of every output instant (the trajectory's, ``sim.output_dt``)
and of every contact event, and, when its ``frame_dt`` [s] is not None, a frame whenever
``frame_dt`` of simulated time has passed since its last one (0: after every step; the run then
computes its states at the finest interval any sink needs, a multiple of ``sim.dt``). A frame's
drawing (``viz3d.frames.Drawing``) is evaluated only if the sink reads it.
"""

from __future__ import annotations

from typing import Protocol

from viz3d.frames import Frame, SceneVisuals


class Sink(Protocol):
    frame_dt: float | None   # read after ``open``

    def open(self, visuals: SceneVisuals) -> None: ...

    def log(self, frame: Frame) -> None: ...

    def event(self, t: float, text: str, level: str = "info") -> None: ...

    def close(self) -> None: ...


#: A sink's frame is due this much [s] before ``frame_dt`` has passed (round-off of step times).
FRAME_SLACK = 1e-12


def frame_due(sink, t: float, last: float) -> bool:
    """Whether ``sink`` wants the frame at ``t`` [s] beyond the output instants, its last frame
    having been at ``last`` [s] (-inf: none yet)."""
    return sink.frame_dt is not None and t >= last + sink.frame_dt - FRAME_SLACK


class NullSink:
    """Accepts and discards everything."""

    frame_dt = None

    def open(self, visuals):
        pass

    def log(self, frame):
        pass

    def event(self, t, text, level="info"):
        pass

    def close(self):
        pass
