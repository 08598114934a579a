"""The bridge's belt speed inputs: one std_msgs/Float64 topic per belt of the scenario."""

from dual_arm_control import contract
from dual_arm_control.core.exceptions import DualArmControlError


def subscribe_belt_speeds(node, twin, warn):
    """
    Subscribe node to the speed topic of each belt twin has; return the subscriptions.

    A speed the twin refuses (not finite) is reported through warn(key, message) and ignored.
    """
    belts = []
    if twin.container is not None:
        belts.append(('outgoing', contract.OUTGOING_BELT_SPEED, twin.set_belt_speed))
    if twin.incoming_belt is not None:
        belts.append(('incoming', contract.INCOMING_BELT_SPEED, twin.set_incoming_belt_speed))
    return [node.create_subscription(
        topic.msg_type, topic.name,
        lambda msg, name=name, apply=apply: _apply_speed(name, apply, msg, warn), topic.qos)
        for name, topic, apply in belts]


def _apply_speed(name, apply, msg, warn):
    """Command one belt's speed from msg, or warn why it is refused."""
    try:
        apply(msg.data)
    except DualArmControlError as error:
        warn((name, 'speed'), f'{name} belt speed {msg.data!r} refused: {error}')
