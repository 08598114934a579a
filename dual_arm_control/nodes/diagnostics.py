"""
A node's counters on /diagnostics, and throttled logging of refused inputs.

Driven by the stamps of the messages the node handles, so it reports in lockstep runs (faster
or slower than real time) as in real time.
"""

import math
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.nodes.messages import time_msg
from dual_arm_control.nodes.process import create_topic_publisher
from dual_arm_control.runtime.timing import seconds_to_ns

LOG_THROTTLE_PERIOD = 1.0


def refusal_logger(logger):
    """Return an on_refusal(reason, count, detail) that logs each reason at most once a second."""
    last_log = {}

    def log(reason, count, detail):
        now = time.monotonic()
        if now - last_log.get(reason, -math.inf) >= LOG_THROTTLE_PERIOD:
            last_log[reason] = now
            logger.warning(f'refused {reason} ({count} so far): {detail}')
    return log


class CounterDiagnostics:
    """
    A node's counters on /diagnostics, at most once per `diagnostics_period` of sim time.

    Reads the node's `diagnostics_period` parameter [s] (declared from its parameter table).
    Driven by the stamps of the messages the node handles, so it reports in lockstep runs
    (faster or slower than real time) as in real time; a stamp earlier than the last report
    (simulation reset) reports at once.
    """

    def __init__(self, node):
        self._node = node
        self._publisher = create_topic_publisher(node, contract.DIAGNOSTICS)
        self._last_ns = None
        self.name = node.get_fully_qualified_name().lstrip('/')

    def publish_if_due(self, t_ns, report):
        """
        Publish report() = (level, message, {key: value}) if a period passed since the last one.

        report is only called when a message goes out. Return True if one was published.
        """
        period_ns = seconds_to_ns(self._node.get_parameter('diagnostics_period').value)
        if self._last_ns is not None and 0 <= t_ns - self._last_ns < period_ns:
            return False
        self._last_ns = t_ns
        level, message, values = report()
        status = DiagnosticStatus(level=level, name=self.name, message=message,
                                  hardware_id=self._node.get_name())
        status.values = [KeyValue(key=key, value=diagnostic_value(value))
                         for key, value in values.items()]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = time_msg(t_ns)
        self._publisher.publish(msg)
        return True


def diagnostic_value(value):
    """Format a diagnostic value: floats to 6 significant digits, the rest as str()."""
    return f'{value:.6g}' if isinstance(value, float) else str(value)
