"""What bag_record reports it matched, read the same way by the bridge and the tests."""


def recorder_matched_counts(msg):
    """Return {topic: publishers matched} of a bag_record status, or None if a count is no int."""
    try:
        return {value.key: int(value.value) for status in msg.status for value in status.values}
    except ValueError:
        return None


def recorder_has_matched(node, matched):
    """Return True if bag_record matched every publisher node sees on each topic it records."""
    return matched is not None and all(node.count_publishers(topic) <= count
                                       for topic, count in matched.items())
