"""Consumers of frames: the live viser viewer, the rerun recorder, and test sinks."""
