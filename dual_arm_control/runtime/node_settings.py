"""
The parameter table of every node: its own settings and the core config tree it tunes.

One source for the rates, periods and node-only parameters. The node shells declare their ROS
parameters from here (with descriptions and ranges), the in-process runner takes its defaults
from here, the launcher checks parameter files against it before starting anything,
docs/parameters.md is generated from it and test_parameter_table checks the shipped config files
with it.
"""

from dataclasses import dataclass

from dual_arm_control.core.motion_config import MotionGeneratorConfig
from dual_arm_control.core.passive_control import PassiveControllerConfig
from dual_arm_control.core.settings import Setting
from dual_arm_control.core.tracker import TrackerConfig
from dual_arm_control.core.wrench_distribution import WrenchDistributorConfig

FRI_PERIODS = (0.001, 0.002, 0.005)
"""FRI send periods the twin runs [s]; torque overlay on the iiwa needs 2 ms or less."""
FRI_PERIOD = 0.002
"""The default FRI cycle [s] (500 Hz)."""
DS_PERIOD = 0.005
"""Period of the motion generator and wrench QP ticks [s] (200 Hz, the paper's rate)."""
COMMAND_TIMEOUT = 0.05
"""Age [s, sim time] beyond which a controller's DS command or contact wrench is stale."""
CONTROLLER_TIMEOUT = 0.01
"""Silence [s, sim time] after which the motion generator counts an arm's controller as lost."""
TF_PERIOD = 0.02
"""Sim time between two /tf updates of one source [s] (50 Hz: enough for viewers, light)."""
MODES = ('lockstep', 'realtime')
TORQUE_INTERFACES = ('full', 'gravity_compensated')
MAX_DURATION = 1.0e6
MAX_OBJECT_DISPLACEMENT = 2.0
OBJECT_MASS_RANGE = (1e-3, 100.0)
MAX_OBJECT_EDGE = 2.0
MAX_WORKSPACE = 5.0
"""Bound of every world coordinate a parameter may give [m]: the cell is a few metres wide."""

DIAGNOSTICS_PERIOD = Setting(
    'diagnostics_period', 1.0, 'sim time between two /diagnostics messages of the node', 's',
    0.01, 100.0)
LOCKSTEP = Setting(
    'lockstep', False, 'wait for every input stamped with the cycle or tick before answering '
    '(deterministic, with the lockstep bridge); false: answer with the newest inputs '
    '(realtime)', read_only=True)
SCENARIO = Setting(
    'scenario', '', 'scenario YAML (path, or name under config/scenarios) whose task, object '
    'and targets give the defaults; empty: built-in defaults', read_only=True)
FRI_PERIOD_SETTING = Setting(
    'fri_period', FRI_PERIOD, 'FRI cycle: joint state out, torque command in', 's',
    choices=FRI_PERIODS, read_only=True)
TORQUE_INTERFACE = Setting(
    'torque_interface', 'full', 'full: the torque command is the whole joint torque (the twin, '
    'a plain torque drive); gravity_compensated: the robot adds its own gravity compensation '
    '(KUKA FRI torque mode), so the controllers leave g(q) out. Controllers and bridge must '
    'agree', choices=TORQUE_INTERFACES, read_only=True)
DS_PERIOD_SETTING = Setting(
    'ds_period', DS_PERIOD, 'period of the DS and wrench QP ticks on the FRI cycle grid', 's',
    0.001, 0.1, read_only=True)


@dataclass(frozen=True)
class NodeTable:
    """A node's parameters: its own settings and, if any, the core config class it tunes."""

    settings: tuple
    config: type = None

    def setting(self, name):
        """Return the node setting called name, or None."""
        return next((entry for entry in self.settings if entry.name == name), None)


NODE_TABLES = {
    'sim_bridge': NodeTable((
        Setting('scenario', 'hold', 'scenario YAML (path, or name under config/scenarios): '
                'cell, object, initial state, seed, perturbations', read_only=True,
                required=True),
        Setting('mode', 'lockstep', 'lockstep: advance when every arm answered '
                '(deterministic); realtime: paced by the wall clock with the FRI watchdog',
                choices=MODES, read_only=True),
        FRI_PERIOD_SETTING, TORQUE_INTERFACE,
        Setting('duration', 0.0, 'sim time at which the run ends and the bridge exits 0; 0 = '
                'the duration of the scenario', 's', 0.0, MAX_DURATION),
        Setting('trajectory_log', '', 'if set: .npz ground-truth trajectory written on exit '
                'and, for the episode it ends, by /sim/reset (empty = none)', read_only=True),
        Setting('seed', -1, "seed of the twin's sensor noise from the start and at every "
                "/sim/reset (read then); -1 = the scenario's", '', -1, 2**32 - 1),
        Setting('at_duration', 'exit', 'at the end of the run (duration): exit 0, or wait (no '
                'more cycles) until /sim/reset starts the next episode',
                choices=('exit', 'wait'), read_only=True),
        Setting('ft_period', DS_PERIOD, 'the F/T readings go out on the first FRI cycle of each '
                'period (TickSchedule: the DS ticks, the only cycles that use them); 0 = every '
                'FRI cycle', 's', 0.0, 0.1, read_only=True),
        Setting('publish_ground_truth', True, 'publish /ground_truth/* topics (evaluation '
                'only, costs CPU)'),
        Setting('ground_truth_period', 0.01, 'sim time between ground-truth messages (for '
                'viewers and bags; the trajectory log has every cycle); 0 = every FRI cycle', 's',
                0.0, 1.0),
        Setting('object_displacement', (0.0, 0.0, 0.0), 'displacement [x, y, z] of the object '
                'in the world applied by the /sim/move_object service', 'm',
                -MAX_OBJECT_DISPLACEMENT, MAX_OBJECT_DISPLACEMENT),
        Setting('lockstep_republish_period', 0.1, 'lockstep: wall time without answers after '
                'which the state is published again', 's', 0.01, 10.0, read_only=True),
        Setting('lockstep_answer_timeout', 0.0, 'lockstep: wall time after which a cycle goes on '
                'without the arms that have not answered (FRI policy: their previous torque '
                'once, then the hold), as a real robot would after its deadline; 0 = wait '
                'forever (deterministic)', 's', 0.0, 60.0, read_only=True),
        Setting('lockstep_wait_for_tracker', False, 'lockstep: publish the mocap samples of a '
                'cycle first and the rest of the state only after the object tracker answered '
                'each of them', read_only=True),
        Setting('wait_for_subscribers', False, 'publish the first state only once every topic '
                'the bridge publishes has a subscriber', read_only=True),
        Setting('wait_for_recorder', False, 'publish the first state only '
                'once bag_record reports that it matched every publisher of its topics the '
                'bridge sees, so a recording loses nothing', read_only=True),
        Setting('wait_for_nodes', ('',), 'publish the first state (and in realtime start the '
                'clock) only once '
                'these nodes (full names, e.g. /ds_motion_generator) and their publishers are in '
                "the graph, plus a settling second ('' entries are ignored)", read_only=True),
        DIAGNOSTICS_PERIOD)),
    'object_tracker': NodeTable((
        Setting('lockstep', False, 'also answer every /clock cycle with the estimate at the '
                'cycle (or that there is none yet), which the lockstep DS and wrench QP wait for; '
                'false: answer the mocap samples only (realtime)', read_only=True),
        Setting('track_container', False, "track a conveyor's container too: filter "
                '/mocap/container_pose and answer each sample and, with lockstep, each cycle on '
                '/container/state (the launcher sets it for a scenario with a conveyor)',
                read_only=True),
        DIAGNOSTICS_PERIOD), TrackerConfig),
    'ds_motion_generator': NodeTable((
        SCENARIO,
        Setting('auto_start_time', 0.0, 'sim time at which an episode starts by itself (after '
                'the FT tare, once an object estimate arrived); 0 = wait for the start service',
                's', 0.0, MAX_DURATION, read_only=True),
        Setting('landing_target', (0.87, 0.0, 0.25), 'landing point of the box centre, world '
                "frame (toss tasks; default: where the scenario's toss lands): setting it "
                're-plans the release state for it, as a point on /dual_arm/landing_target '
                'does, or is refused with the reason (out of reach, or after the release)',
                'm', -MAX_WORKSPACE, MAX_WORKSPACE),
        Setting('controller_timeout', CONTROLLER_TIMEOUT, 'sim time without a torque command '
                'from the controller of an arm (heard before) after which it counts as lost: the '
                'task stops where it is, a held box stays squeezed against the arm the robot '
                'holds; 0 = never', 's', 0.0, 1.0, read_only=True),
        Setting('release_latency_lead', True, 'realtime: the toss releases earlier by the '
                'mean lag of the DS commands the controllers run on, as they report it on '
                '/diagnostics (runtime.command_latency; 3.5-4.5 ms on 2 cores), on top of the '
                'phases release_lead_time; false: release_lead_time only. Lockstep has no lag',
                read_only=True),
        DS_PERIOD_SETTING, LOCKSTEP, DIAGNOSTICS_PERIOD), MotionGeneratorConfig),
    'wrench_qp': NodeTable((
        SCENARIO,
        Setting('object_mass', 0.7, 'mass of the grasped box (default: the object of the '
                'scenario, else the catalogue paper_cube); applied at the next tick outside a '
                'grasp',
                'kg', *OBJECT_MASS_RANGE),
        Setting('object_size', (0.2, 0.2, 0.2), 'edge lengths of the box along object x, y '
                '(squeeze axis), z (default: the object of the scenario); applied at the next '
                'tick outside a grasp', 'm', 0.0, MAX_OBJECT_EDGE, low_open=True),
        LOCKSTEP, DIAGNOSTICS_PERIOD), WrenchDistributorConfig),
    'passive_controller': NodeTable((
        Setting('arm', '', 'which arm this controller drives (no default: set it per '
                'namespace)', choices=('left', 'right'), read_only=True),
        Setting('lockstep', True, LOCKSTEP.description, read_only=True),
        FRI_PERIOD_SETTING, DS_PERIOD_SETTING, TORQUE_INTERFACE,
        Setting('command_timeout', COMMAND_TIMEOUT, 'a ds_command or contact_wrench further '
                'than this from the cycle is stale: hold torque / no wrench (sim time; must '
                'exceed ds_period + fri_period)', 's', 0.0, 1.0, low_open=True),
        DIAGNOSTICS_PERIOD), PassiveControllerConfig),
    'cell_state_publisher': NodeTable((
        Setting('scenario', '', 'scenario YAML (path, or name under config/scenarios) whose '
                'targets (release, landing, place) become static TF frames; empty: none',
                read_only=True),
        Setting('tf_period', TF_PERIOD, 'sim time between two /tf updates of one source (each '
                'arm from its joint states, the object from /object/state)', 's', 0.001, 1.0))),
    'gravity_comp_controller': NodeTable((
        Setting('arm', '', 'which arm this test controller drives (no default: set it per '
                'namespace)', choices=('left', 'right'), read_only=True),
        Setting('mode', 'gravity', 'gravity: gravity torque - damping * velocity; zero: no '
                'torque (the arm falls)', choices=('gravity', 'zero')),
        Setting('joint_damping', 2.0, 'viscous joint damping added to the gravity torque',
                'N m s/rad', 0.0, 100.0),
        Setting('mute_window', (0.0, 0.0), 'sim time interval [start, end) whose joint states '
                'are not answered (a stalled controller, for fault tests); empty by default',
                's', 0.0, MAX_DURATION))),
}


def node_table(executable):
    """Return the NodeTable of a node executable; KeyError names the known ones."""
    try:
        return NODE_TABLES[executable]
    except KeyError:
        raise KeyError(f'no parameter table for {executable!r}; known: '
                       f'{", ".join(sorted(NODE_TABLES))}') from None


def controller_parameter_problem(values):
    """Return why a controller's fri_period, ds_period and command_timeout disagree, or None."""
    fri = values.get('fri_period', FRI_PERIOD)
    ds = values.get('ds_period', DS_PERIOD)
    timeout = values.get('command_timeout', COMMAND_TIMEOUT)
    if ds < fri:
        return f'ds_period = {ds:g} s must be at least fri_period = {fri:g} s'
    if timeout <= ds + fri:
        return (f'command_timeout = {timeout:g} s must exceed ds_period + fri_period = '
                f'{ds + fri:g} s, the longest gap between two DS commands')
    return None
