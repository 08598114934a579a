"""
Random parameter sets through the standard parameter services of a running lockstep graph.

Over the episode, PARAMETER_SETS times: pick a node and one of its writable parameters; with
equal chance set a valid value (uniform in the declared range, or a boolean) or an invalid one
(beyond the range, NaN, Inf, or the wrong type). Every invalid set must be refused with its
reason; valid ones may change the task, never the safety: no node exits, no NaN torque, none
beyond the limits.
"""

import math

from dual_arm_control.tools.faults.graph_run import GraphRun
from dual_arm_control.tools.faults.outcome import bag_status, TrialOutcome
from dual_arm_control.tools.faults.trial import measure_graph_episode
import numpy as np
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

# The control nodes; the bridge's parameters steer the run itself (its duration, ground truth).
FUZZED_NODES = ('/ds_motion_generator', '/wrench_qp', '/object_tracker',
                '/left/passive_controller', '/right/passive_controller')
PARAMETER_SETS = 30
FUZZ_WINDOW = (0.4, 2.4)
SERVICE_TIMEOUT = 20.0
NUMBER_TYPES = (ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_INTEGER)


def _call(run, future):
    run.probe.spin_until(future.done, SERVICE_TIMEOUT)
    return future.result() if future.done() else None


def writable_parameters(run, client):
    """Return the descriptors of a node's writable parameters (not use_sim_time)."""
    listed = _call(run, client.list_parameters())
    if listed is None:
        return []
    names = [name for name in listed.result.names if name != 'use_sim_time']
    described = _call(run, client.describe_parameters(names))
    if described is None:
        return []
    return [d for d in described.descriptors if not d.read_only]


def _range(descriptor):
    ranges = list(descriptor.floating_point_range) or list(descriptor.integer_range)
    return (ranges[0].from_value, ranges[0].to_value) if ranges else None


def draw_value(descriptor, rng):
    """Return (valid, rclpy Parameter) for a descriptor, or None if it cannot be fuzzed."""
    bounds = _range(descriptor)
    kind = descriptor.type
    if kind == ParameterType.PARAMETER_BOOL:
        if rng.uniform() < 0.5:
            return True, Parameter(descriptor.name, Parameter.Type.BOOL, bool(rng.integers(2)))
        return False, Parameter(descriptor.name, Parameter.Type.STRING, 'maybe')
    if kind not in NUMBER_TYPES or bounds is None:
        return None
    low, high = bounds
    integer = kind == ParameterType.PARAMETER_INTEGER
    if rng.uniform() < 0.5:
        value = rng.integers(low, high + 1) if integer else rng.uniform(low, high)
        return True, Parameter(descriptor.name, value=int(value) if integer else float(value))
    span = max(high - low, 1.0)
    choices = [low - span, high + span]
    if not integer:
        choices += [math.nan, math.inf]
    pick = rng.integers(len(choices) + 1)
    if pick == len(choices):
        return False, Parameter(descriptor.name, Parameter.Type.STRING, 'fast')
    value = choices[pick]
    return False, Parameter(descriptor.name, value=int(value) if integer else float(value))


def parameter_fuzz(kind, trial):
    """Run the trial's episode in the graph while setting random parameters; see the module."""
    rng = np.random.default_rng([trial.index, 16])
    outcome = TrialOutcome(kind, trial.index, trial.seed, fault_time=FUZZ_WINDOW[0])
    accepted_invalid, refused_valid, refused = [], 0, 0
    with GraphRun(trial.scenario_file(), trial.out_dir, trial.domain,
                  trial.scenario.duration) as run:
        run.wait_for_sim_time(FUZZ_WINDOW[0], SERVICE_TIMEOUT * 5)
        clients = {name: AsyncParameterClient(run.probe.node, name) for name in FUZZED_NODES}
        descriptors = {}
        for name, client in clients.items():
            if run.probe.spin_until(client.services_are_ready, SERVICE_TIMEOUT):
                descriptors[name] = writable_parameters(run, client)
        step = (FUZZ_WINDOW[1] - FUZZ_WINDOW[0]) / PARAMETER_SETS
        for index in range(PARAMETER_SETS):
            if not run.wait_for_sim_time(FUZZ_WINDOW[0] + index * step, SERVICE_TIMEOUT * 5):
                break
            name = FUZZED_NODES[rng.integers(len(FUZZED_NODES))]
            candidates = descriptors.get(name) or []
            drawn = None
            while candidates and drawn is None:
                drawn = draw_value(candidates[rng.integers(len(candidates))], rng)
            if drawn is None:
                continue
            valid, parameter = drawn
            result = _call(run, clients[name].set_parameters([parameter]))
            if result is None:
                continue
            successful = result.results[0].successful
            refused += not successful
            refused_valid += valid and not successful
            if not valid and successful:
                accepted_invalid.append(f'{name} {parameter.name}={parameter.value!r}')
        exits = run.wait_for_end(SERVICE_TIMEOUT * 15)
    outcome.node_exits = sum(1 for label, code in exits.items()
                             if (label, code) != ('sim_bridge', 0))
    outcome.refused = refused
    outcome.bag_status = bag_status(run.bag_file)
    outcome.note = (f'{refused} sets refused ({refused_valid} of them valid); invalid accepted: '
                    f'{accepted_invalid}')
    outcome = measure_graph_episode(outcome, run.trajectory_file, trial)
    outcome.held = outcome.held and not accepted_invalid and outcome.node_exits == 0
    return outcome
