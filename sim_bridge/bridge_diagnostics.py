"""
The bridge's counters: their values (saved in the trajectory log too) and /diagnostics.

One status for the bridge (mode, sim time, cycles, late cycles, stalls and the longest gap
between two cycles in realtime, real-time factor) and one per
arm with the FRI counters; an arm is WARN once anything was refused, clamped or held.
"""

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from dual_arm_control import contract
from dual_arm_control.nodes.diagnostics import diagnostic_value
from dual_arm_control.nodes.messages import time_msg
from dual_arm_control.runtime.fri import REFUSAL_REASONS


def counter_values(mode, twin, fri, cycle_gaps, first_cycle_wall):
    """
    Return {status name: {key: value}} of the counters; first_cycle_wall None: not started.

    cycle_gaps: the CycleGaps of the realtime FRI clock (zero in lockstep).
    """
    wall = time.monotonic() - first_cycle_wall if first_cycle_wall else 0.0
    bridge = {'mode': mode, 'sim_time': twin.time, 'cycles': fri.cycles,
              **cycle_gaps.as_dict(),
              'real_time_factor': twin.time / wall if wall > 0.0 else 0.0}
    values = {'sim_bridge': bridge}
    for arm in contract.ARMS:
        values[f'sim_bridge: {arm} arm'] = fri.counters[arm].as_dict()
    return values


def diagnostics_message(values, stamp_ns):
    """Return the DiagnosticArray of counter_values() stamped stamp_ns."""
    msg = DiagnosticArray()
    msg.header.stamp = time_msg(stamp_ns)
    for name, status_values in values.items():
        status = DiagnosticStatus(name=name, hardware_id='sim_bridge')
        trouble = (status_values.get('watchdog_holds', 0)
                   + status_values.get('torque_clamps', 0)
                   + sum(status_values.get(f'refused_{r}', 0) for r in REFUSAL_REASONS))
        stalls = status_values.get('cycle_stalls', 0)
        status.level = DiagnosticStatus.WARN if trouble or stalls else DiagnosticStatus.OK
        status.message = ('commands refused, clamped or missing' if trouble else
                          f'{stalls} stalls of the FRI clock' if stalls else 'ok')
        status.values = [KeyValue(key=key, value=diagnostic_value(value))
                         for key, value in status_values.items()]
        msg.status.append(status)
    return msg
