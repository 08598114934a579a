"""
Torque commands signed by the graph's controllers, so the bridge applies no one else's.

Any process on the ROS domain may publish on an arm's torque command topic, and rclpy does not
say which publisher a message came from. So the launcher hands every node it starts one random
key per launch, in the environment (COMMAND_KEY_VARIABLE; a parameter would be readable through
the parameter services): a controller puts an HMAC-SHA256 of its command (stamp, joint names,
efforts) in header.frame_id, and a bridge with the key takes only commands signed with it. A
node without the key in its environment neither signs nor checks (a bridge or controller
started alone, as the tests do). The signature is compared with ==: a process that could time
that comparison runs as the same user and could read the key from the nodes' environment.
"""

from functools import lru_cache
import hashlib
import os
import secrets
import struct

import numpy as np

COMMAND_KEY_VARIABLE = 'DUAL_ARM_COMMAND_KEY'


@lru_cache(maxsize=1)
def launch_key():
    """Return the key for the nodes this process launches: the inherited one, else a new one."""
    return os.environ.get(COMMAND_KEY_VARIABLE) or secrets.token_hex(16)


def command_key():
    """Return the key in this node's environment (bytes), or None."""
    key = os.environ.get(COMMAND_KEY_VARIABLE)
    return key.encode() if key else None


def command_signature(key, stamp_ns, names, efforts):
    """
    Return the signature (hex) of a torque command: its stamp [ns], joint names, efforts.

    HMAC-SHA256 of the command with key: PBKDF2 with one iteration is one HMAC (of the payload
    followed by the block counter).
    """
    payload = (struct.pack('<q', int(stamp_ns)) + '\n'.join(names).encode()
               + np.asarray(efforts, dtype=float).tobytes())
    return hashlib.pbkdf2_hmac('sha256', key, payload, 1).hex()


def signed(key, stamp_ns, names, efforts, signature):
    """Return True if signature is the command's signature with key."""
    return command_signature(key, stamp_ns, names, efforts) == signature
