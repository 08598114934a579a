"""
Time the warm-started wrench QP (eq. 10) and one passive-DS controller tick.

Run: python -m dual_arm_control.benchmarks.qp_controller_bench [--ticks N]

The QP sees a grasped 0.2 m cube carried along a smooth path at 200 Hz (geometry and desired
wrench change a little each tick, as in operation), including one release and re-grasp of
the left pad; it is timed back to back and interleaved with other work. The controller ticks
at 1 kHz inside a pinocchio forward-dynamics simulation of each arm tracking a linear DS.
Only the core calls are timed. Prints median and p99 in microseconds; targets are 80 us (QP)
and 60 us (controller tick).
"""

import argparse
import time

from dual_arm_control.core.geometry import rotation_exp
from dual_arm_control.core.object_wrench import box_inertia, desired_object_wrench
from dual_arm_control.core.pad_contact import pad_contact_geometry, PAD_ORDER
from dual_arm_control.core.passive_control import PassiveController
from dual_arm_control.core.wrench_qp import ContactWrenchQP
from dual_arm_control.description.cell import arm_model, load_cell
import numpy as np

QP_RATE = 200.0
CONTROL_DT = 0.001
OBJECT_SIZE = np.array([0.2, 0.2, 0.2])
OBJECT_MASS = 0.7


def carried_object_state(time_s):
    """Return (p_world_object, R_world_object, v, w, v_desired) on a smooth carrying path."""
    p = np.array([0.45 + 0.15 * np.sin(time_s), 0.02 * np.sin(0.5 * time_s),
                  0.35 + 0.1 * np.sin(1.3 * time_s)])
    v = np.array([0.15 * np.cos(time_s), 0.01 * np.cos(0.5 * time_s),
                  0.13 * np.cos(1.3 * time_s)])
    R = rotation_exp([0.2 * np.sin(0.8 * time_s), 0.0, 0.3 * np.sin(0.6 * time_s)])
    w = np.array([0.16 * np.cos(0.8 * time_s), 0.0, 0.18 * np.cos(0.6 * time_s)])
    return p, R, v, w, v + 0.05 * np.array([np.sin(3 * time_s), 0.0, np.cos(2 * time_s)])


def pad_contacts(time_s, p_world_object, R_world_object, left_gap):
    """Return the PadContact of both pads, the left one left_gap [m] off its face."""
    contacts = {}
    for arm in PAD_ORDER:
        sign = 1.0 if arm == 'left' else -1.0
        z_axis = -sign * R_world_object[:, 1]
        x_axis = R_world_object[:, 0]
        R_world_tool = np.column_stack((x_axis, np.cross(z_axis, x_axis), z_axis))
        gap = left_gap if arm == 'left' else 0.0
        offset = np.array([0.01 * np.sin(time_s), sign * (0.1 + gap), -0.01])
        contacts[arm] = pad_contact_geometry(arm, p_world_object + R_world_object @ offset,
                                             R_world_tool, p_world_object, R_world_object,
                                             OBJECT_SIZE)
    return contacts


def qp_inputs(ticks):
    """Return [(object_wrench, p_world_object, contacts)] for ticks + 1 QP ticks."""
    inertia = box_inertia(OBJECT_MASS, OBJECT_SIZE)
    inputs = []
    for tick in range(ticks + 1):
        time_s = tick / QP_RATE
        p, R, v, w, v_desired = carried_object_state(time_s)
        left_gap = 0.08 if ticks // 2 <= tick < ticks // 2 + 20 else 0.0
        object_wrench = desired_object_wrench(v, w, v_desired, np.zeros(3), OBJECT_MASS,
                                              R @ inertia @ R.T)
        inputs.append((object_wrench, p, pad_contacts(time_s, p, R, left_gap)))
    return inputs


def benchmark_qp(inputs, interleave):
    """
    Return (call times [s], iteration counts, infeasible ticks) of the warm QP.

    With interleave, other Python work (a 200k-element numpy sum, about what a node does
    between two 200 Hz ticks) runs between calls, so caches are not warm as in a tight loop.
    """
    solver = ContactWrenchQP()
    other_work = np.random.default_rng(0).random(200_000)
    times, iterations, infeasible = [], [], 0
    for tick, (object_wrench, p_world_object, contacts) in enumerate(inputs):
        if interleave:
            other_work.sum()
        start = time.perf_counter()
        result = solver.contact_wrenches(object_wrench, p_world_object, contacts)
        elapsed = time.perf_counter() - start
        if tick == 0:
            continue
        times.append(elapsed)
        iterations.append(result.iterations)
        infeasible += not result.feasible
    return np.array(times), np.array(iterations), infeasible


def benchmark_controller(arm, ticks):
    """Return the tick times [s] of the passive controller of one arm in closed loop."""
    cell = load_cell()
    model = arm_model(arm, cell)
    q = cell.arm(arm).q_home.copy()
    dq = np.zeros(7)
    controller = PassiveController(model, q)
    p_world_start, R_world_start = model.tool_pose(q)
    target = p_world_start + np.array([0.1, -0.05, -0.1])
    times = []
    for _ in range(ticks):
        p_world_tool, _ = model.tool_pose(q)
        v_desired = -3.0 * (p_world_tool - target)
        start = time.perf_counter()
        command = controller.torque_command(q, dq, v_desired, np.zeros(3), R_world_start)
        times.append(time.perf_counter() - start)
        dq = dq + CONTROL_DT * model.forward_dynamics(q, dq, command.torque)
        q = q + CONTROL_DT * dq
    return np.array(times)


def _summary(name, times, target_us):
    micro = 1e6 * times
    print(f'{name}: median {np.median(micro):6.1f} us, p99 {np.percentile(micro, 99):6.1f} us, '
          f'max {micro.max():7.1f} us over {micro.size} ticks (target <= {target_us} us)')


def main(argv=None):
    """Run both benchmarks and print the numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--ticks', type=int, default=3000, help='ticks per benchmark (>= 2000)')
    args = parser.parse_args(argv)
    inputs = qp_inputs(args.ticks)
    for interleave in (False, True):
        times, iterations, infeasible = benchmark_qp(inputs, interleave)
        label = 'interleaved with other work' if interleave else 'back to back'
        _summary(f'wrench QP contact_wrenches, warm, {label}', times, 80)
    print(f'  proxsuite iterations per call: median {np.median(iterations):.0f}, max '
          f'{iterations.max()} (contact changes start cold); ticks with slack (left pad '
          f'released for 20 ticks): {infeasible}')
    for arm in ('left', 'right'):
        _summary(f'passive controller tick ({arm})', benchmark_controller(arm, args.ticks), 60)


if __name__ == '__main__':
    main()
