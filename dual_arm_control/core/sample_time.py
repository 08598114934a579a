"""
When joint samples were taken, for velocities differenced between DS ticks.

A DS tick reads the newest joint state of each arm. In lockstep that is the tick's own cycle; in
realtime it may be a cycle or two (2-4 ms) older or newer than the tick. A tool position
differenced over the 5 ms tick then reads 20-40 % fast or slow from one tick to the next; over
the time between the two samples it reads the tools' motion. An ArmMeasurement carries its
sample_age (how long before the tick its joint state was sampled).
"""

import numpy as np

SAME_SAMPLE_SPAN = 1e-4
"""Spans [s] below this are one joint sample read at two ticks (FRI cycles are 1-5 ms apart)."""


def sample_span(dt, previous_age, age):
    """
    Return the time [s] between two ticks' joint samples, or None if a sample was read twice.

    dt [s]: from the previous tick to this one; previous_age, age [s] (scalars or arrays, one
    per arm): how long before its tick each sample was taken. Equal to dt in lockstep (ages 0).
    """
    span = dt + np.asarray(previous_age, dtype=float) - age
    return None if np.any(span <= SAME_SAMPLE_SPAN) else span
