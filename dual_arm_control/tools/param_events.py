"""
Parameter changes recorded in a bag: the /parameter_events messages of an MCAP bag, in order.

parameter_changes lists every new, changed and deleted parameter with the node that announced
it, its value, the event's stamp and the recorder's log time.
"""

from dataclasses import dataclass

from dual_arm_control.bags import BagError
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.core.exceptions import InputError
from rcl_interfaces.msg import ParameterEvent
from rclpy.parameter import parameter_value_to_python
from rclpy.serialization import deserialize_message

PARAMETER_EVENTS_TOPIC = '/parameter_events'


@dataclass(frozen=True)
class ParameterChange:
    """One parameter of a /parameter_events message: kind is 'new', 'changed' or 'deleted'."""

    stamp_ns: int
    log_time_ns: int
    node: str
    name: str
    value: object
    kind: str


def _event_changes(event, log_time_ns):
    """Return the ParameterChange list of one ParameterEvent message."""
    stamp_ns = event.stamp.sec * 1_000_000_000 + event.stamp.nanosec
    return [ParameterChange(stamp_ns, log_time_ns, event.node, parameter.name,
                            parameter_value_to_python(parameter.value), kind)
            for kind, parameters in (('new', event.new_parameters),
                                     ('changed', event.changed_parameters),
                                     ('deleted', event.deleted_parameters))
            for parameter in parameters]


def parameter_changes(bag_path):
    """
    Return the ParameterChange list of a bag's /parameter_events, in log-time order.

    stamp_ns is the event's stamp (the node's clock), log_time_ns the recorder's. Split files
    (<stem>_<N>.mcap) of the bag are read too.
    """
    try:
        messages = list(BagReader(bag_path).messages([PARAMETER_EVENTS_TOPIC]))
    except BagError as error:
        raise InputError(f'{bag_path}: cannot read bag: {error}') from None
    changes = []
    for message in messages:
        changes += _event_changes(deserialize_message(message.data, ParameterEvent),
                                  message.log_time)
    return sorted(changes, key=lambda change: change.log_time_ns)
