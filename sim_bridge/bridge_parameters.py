"""The sim_bridge node's parameters: declarations with descriptions and ranges, validation."""

import math

from dual_arm_control import contract
from dual_arm_control.parameters import parameter_descriptor
from dual_arm_control.resources import config_path

MODES = ('lockstep', 'realtime')
FRI_PERIODS = (0.001, 0.002, 0.005)
MAX_DURATION = 1.0e6
MAX_OBJECT_DISPLACEMENT = 2.0


def parameter_problem(name, value):
    """Return why a bridge parameter value is invalid, or None if it is acceptable."""
    if name == 'mode' and value not in MODES:
        return f'mode must be one of {MODES}, got {value!r}'
    if name == 'fri_period' and not any(math.isclose(value, p) for p in FRI_PERIODS):
        return f'fri_period must be one of {FRI_PERIODS} s (FRI send periods), got {value!r}'
    if name == 'duration' and not 0.0 <= value <= MAX_DURATION:
        return f'duration must be in [0, {MAX_DURATION:g}] s (0: scenario duration), got {value}'
    if name == 'object_displacement':
        if len(value) != 3 or not all(math.isfinite(v) for v in value):
            return f'object_displacement must be 3 finite numbers [m], got {list(value)}'
        if max(abs(v) for v in value) > MAX_OBJECT_DISPLACEMENT:
            return (f'object_displacement components must be within +-{MAX_OBJECT_DISPLACEMENT}'
                    f' m, got {list(value)}')
    if name == 'scenario' and not value:
        return 'scenario must name a scenario YAML file'
    if name == 'lockstep_republish_period' and not 0.01 <= value <= 10.0:
        return f'lockstep_republish_period must be in [0.01, 10] s, got {value}'
    if name == 'diagnostics_period' and not 0.01 <= value <= 100.0:
        return f'diagnostics_period must be in [0.01, 100] s, got {value}'
    if name == 'ground_truth_period' and not 0.0 <= value <= 1.0:
        return f'ground_truth_period must be in [0, 1] s (0: every cycle), got {value}'
    return None


def declare_bridge_parameters(node):
    """Declare every parameter of the bridge with its description, range and mutability."""
    declare = node.declare_parameter
    declare('scenario', str(config_path('scenarios', 'hold.yaml')), parameter_descriptor(
        'scenario YAML: cell, object, initial state, seed, perturbations', read_only=True))
    declare('mode', 'lockstep', parameter_descriptor(
        'lockstep: advance when every arm answered (deterministic); realtime: paced by the wall '
        'clock with the FRI watchdog', read_only=True, constraints=f'one of {MODES}'))
    declare('fri_period', 0.002, parameter_descriptor(
        'FRI cycle: state out, torque command in [s]', read_only=True,
        floating_range=(FRI_PERIODS[0], FRI_PERIODS[-1]), constraints=f'one of {FRI_PERIODS}'))
    declare('duration', 0.0, parameter_descriptor(
        'sim time at which the run ends and the bridge exits 0 [s]; 0 = the duration of the '
        'scenario', floating_range=(0.0, MAX_DURATION)))
    declare('trajectory_log', '', parameter_descriptor(
        'if set: .npz ground-truth trajectory written on exit (empty = none)', read_only=True))
    declare('publish_ground_truth', True, parameter_descriptor(
        'publish /ground_truth/* topics (evaluation only, costs CPU)'))
    declare('ground_truth_period', 0.0, parameter_descriptor(
        'sim time between ground-truth messages [s]; 0 = every FRI cycle',
        floating_range=(0.0, 1.0)))
    declare('object_displacement', [0.0, 0.0, 0.0], parameter_descriptor(
        'displacement [x, y, z] applied by the move_object service [m]',
        constraints=f'each component within +-{MAX_OBJECT_DISPLACEMENT} m'))
    declare('lockstep_republish_period', 0.1, parameter_descriptor(
        'lockstep: wall time without answers after which the state is published again [s]',
        read_only=True, floating_range=(0.01, 10.0)))
    declare('lockstep_wait_for_tracker', False, parameter_descriptor(
        'lockstep: publish the mocap samples of a cycle first and the rest of the state only '
        'after the object tracker answered each of them (an /object/state with the stamp of '
        'the sample)', read_only=True))
    declare('lockstep_wait_for_subscribers', False, parameter_descriptor(
        'lockstep: publish the first state only once every topic the bridge publishes has a '
        'subscriber (a recorder that must see every cycle)', read_only=True))
    declare('lockstep_wait_for_recorder', False, parameter_descriptor(
        'lockstep: publish the first state only once bag_record reports (on '
        f'{contract.RECORDER_STATUS.name}) that it matched every publisher of its topics the '
        'bridge sees, so a recording loses nothing', read_only=True))
    declare('lockstep_wait_for_nodes', [''], parameter_descriptor(
        'lockstep: publish the first state only once these nodes (full names, e.g. '
        '/ds_motion_generator, /bag_record) and their publishers are in the graph, plus a '
        "settling second, so every node sees the run from its first cycle ('' entries are "
        'ignored)', read_only=True))
    declare('diagnostics_period', 1.0, parameter_descriptor(
        'sim time between /diagnostics messages [s]', floating_range=(0.01, 100.0)))
