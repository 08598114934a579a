"""
Input bookkeeping shared by every role: refusal counts and the lockstep arrival barrier.

A role computes a tick from several inputs that arrive on their own (joint states, FT, the
object estimate, the DS command...). In lockstep the role must compute tick t only once every
input stamped t is in, whatever order the messages came in; ArrivalBarrier says when that is.
The values themselves stay with the role as its newest valid inputs: an input that was refused
still counts as arrived (the tick goes on with the newest valid value), so a malformed message
never stalls the graph.
"""

MAX_PENDING_STAMPS = 64
# A stamp this much older than the last completed one means the clock went back (simulation
# reset), not a late message: the pending stamps of the old timeline are dropped [ns].
TIME_RESET_GAP_NS = 100_000_000


class RefusalCounter:
    """Count refused inputs per reason; on_refusal(reason, count, detail) is told of each."""

    def __init__(self, on_refusal=None):
        self.counts = {}
        self._on_refusal = on_refusal

    def refuse(self, reason, detail):
        """Count one refusal of the given reason; detail says what was wrong."""
        self.counts[reason] = self.counts.get(reason, 0) + 1
        if self._on_refusal is not None:
            self._on_refusal(reason, self.counts[reason], detail)

    @property
    def total(self):
        """Return the number of refusals of every reason."""
        return sum(self.counts.values())


class ArrivalBarrier:
    """
    Which stamps have all their inputs: required(stamp) names the inputs a stamp needs.

    arrived() returns the stamps it completes, oldest first. Incomplete stamps older than a
    completed one are dropped (counted): their missing inputs will not come any more, or
    never were due (a role that ticks on some cycles only sees the other cycles' inputs go
    by). At most MAX_PENDING_STAMPS incomplete stamps are kept, so a lost message costs
    bounded memory. A stamp TIME_RESET_GAP_NS older than the last completed one starts a new
    timeline (the clock went back): every pending stamp of the old one is dropped. A stamp more
    than TIME_RESET_GAP_NS after the last completed one is no next cycle (lockstep advances one
    cycle at a time) but a stray message's, e.g. refused inputs stamped in the future: it
    completes alone, dropping nothing, so the cycle the graph waits for still completes.
    """

    def __init__(self, required):
        self._required = required
        self._arrivals = {}
        self._last_complete = None
        self.dropped = 0

    def arrived(self, stamp_ns, name):
        """Record that input `name` of stamp_ns arrived; return the stamps now complete."""
        if (self._last_complete is not None
                and self._last_complete - stamp_ns > TIME_RESET_GAP_NS):
            self.dropped += len(self._arrivals)
            self._arrivals.clear()
            self._last_complete = None
        self._arrivals.setdefault(stamp_ns, set()).add(name)
        complete = [stamp for stamp in sorted(self._arrivals)
                    if self._arrivals[stamp] >= self._required(stamp)]
        if not complete:
            while len(self._arrivals) > MAX_PENDING_STAMPS:
                del self._arrivals[min(self._arrivals)]
                self.dropped += 1
            return []
        stray = [stamp for stamp in complete if self._last_complete is not None
                 and stamp - self._last_complete > TIME_RESET_GAP_NS]
        for stamp in stray:
            del self._arrivals[stamp]
        if len(stray) == len(complete):
            return stray
        newest = complete[-len(stray) - 1]
        complete = complete[:len(complete) - len(stray)]
        self._last_complete = newest
        for stamp in [s for s in self._arrivals if s <= newest]:
            if stamp not in complete:
                self.dropped += 1
            del self._arrivals[stamp]
        return complete + stray

    def pending(self, stamp_ns):
        """Return the inputs stamp_ns still waits for (empty if complete or unknown)."""
        return self._required(stamp_ns) - self._arrivals.get(stamp_ns, set())
