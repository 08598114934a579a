"""The two arms of the cell and the names of their joints."""

ARMS = ('left', 'right')
"""Arm names; stacked per-arm arrays use this order (row 0 left, row 1 right)."""
JOINTS_PER_ARM = 7


def joint_names(arm):
    """Return the seven joint names of an arm as messages and the URDFs spell them."""
    if arm not in ARMS:
        raise ValueError(f'unknown arm {arm!r}; expected one of {ARMS}')
    return [f'{arm}_A{index}' for index in range(1, JOINTS_PER_ARM + 1)]
