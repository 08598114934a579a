"""
How late realtime DS commands act on the arms, for the toss release's lead (section IV-A).

The paper lets go of the box at the release state. In lockstep a controller answers each DS
tick's cycle with that tick's command. In realtime a controller runs on the newest command it
has, which on a 2-core machine is a tick or more old in three cycles of four (3.5-4.5 ms on
average). The arms then follow the toss field late all through the throw, and the box crosses
the release plane fast: up to 25 % over the release speed, median 4 %. In-process runs with the
DS commands handed over 8 ms late reproduce that, and a release 8 ms earlier removes it.

Each controller measures that lag where it happens: the mean, over its cycles, of the time from
the tick of the command it used to the newest tick due (runtime.controller_step), reported on
/diagnostics. CommandLatency keeps the newest report of each controller; the latency is their
mean, each at most `limit` (a stalled graph must not release the box far early), and 0 before
any report.
"""

import math


class CommandLatency:
    """The DS command lag [s] the controllers report: the toss release leads by it."""

    def __init__(self, limit=0.02):
        if not limit > 0.0:
            raise ValueError(f'limit must be positive, got {limit}')
        self._limit = limit
        self._lags = {}

    def reported(self, controller, lag):
        """Keep controller's (a name) newest mean lag [s]; return False if it is not a lag."""
        if not (isinstance(lag, float) and math.isfinite(lag) and lag >= 0.0):
            return False
        self._lags[controller] = min(lag, self._limit)
        return True

    @property
    def seconds(self):
        """Return the mean of the controllers' newest lags [s], 0 before any report."""
        return sum(self._lags.values()) / len(self._lags) if self._lags else 0.0
