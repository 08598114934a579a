"""
dual_arm_bringup: start the graph as separate processes, run one episode, write its results.

The scenario (a file, or the name of a shipped one) and the parameter file are checked before
any process starts. Each node runs in its own process in a ROS domain reserved for the run
(domain_coordinator), with its log in OUT/logs/; phase changes are echoed as they happen.
Ctrl-C or SIGTERM stops every child within a few seconds. With --scenario the episode ends when
the bridge reaches the scenario's duration; metrics.json and plots are then written to --out.

Exit codes: 0 the episode met its task criteria (or a run without scenario was stopped
cleanly); 1 the task failed; 2 bad input (scenario, parameter file, options), nothing started;
3 a node died, timed out or left no result; 130 interrupted during an episode.
"""

import argparse
import ctypes
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from domain_coordinator import domain_id
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.executables import EXECUTABLES
from dual_arm_control.graph import GRAPHS, run_parameters
from dual_arm_control.nodes.command_signature import COMMAND_KEY_VARIABLE, launch_key
from dual_arm_control.nodes.ds_motion_generator import phase_log_events, PHASE_LOG_PREFIX
from dual_arm_control.nodes.process import REALTIME_PRIORITY_VARIABLE
from dual_arm_control.parameter_files import key_applies, parameter_file_problems
from dual_arm_control.resources import config_path, load_yaml
from dual_arm_control.scenario import load_scenario, scenario_path

# Highest ROS domain id Fast DDS accepts on the default port mapping.
MAX_DOMAIN_ID = 232
EXIT_SUCCESS, EXIT_TASK_FAILED, EXIT_BAD_INPUT, EXIT_NODE_FAILED, EXIT_INTERRUPTED = (
    0, 1, 2, 3, 130)
LOG_TAIL_LINES = 8
STOP_GRACE_PERIOD = 4.0
RECORDER_STARTUP_TIMEOUT = 15.0
POLL_PERIOD = 0.1
_PR_SET_PDEATHSIG = 1


def _die_with_parent():
    """Ask the kernel to SIGTERM this child if the launcher dies, so nothing is orphaned."""
    try:
        ctypes.CDLL('libc.so.6', use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass


def executable_command(executable):
    """Return the argv that runs one of the package's executables with this Python."""
    module, function = EXECUTABLES[executable].split(':')
    return [sys.executable, '-c',
            f'import sys; from {module} import {function}; sys.exit({function}())']


def node_command(spec, ros_arguments, skip=()):
    """Return the argv of one node of the table, its parameters but those in skip, arguments."""
    args = executable_command(spec.executable) + ['--ros-args', '-r', f'__node:={spec.name}']
    if spec.namespace:
        args += ['-r', f'__ns:={spec.namespace}']
    for param_file in spec.param_files:
        args += ['--params-file', str(config_path(param_file))]
    for name, value in spec.parameters.items():
        if name in skip:
            continue
        args += ['-p', f'{name}:={ros_value(value)}']
    return args + list(ros_arguments)


def user_parameter_names(user_parameters, spec):
    """
    Return the parameter names a user's ROS parameter file sets for one node.

    `-p` overrides win over parameter files in ROS 2 whatever their order, so the launcher
    leaves out its own per-run value of any parameter the user's file sets: the user's file
    has the last word. Keys may be the node name, its namespaced name or a `/**` wildcard.
    """
    names = set()
    for key, entry in user_parameters.items():
        if key_applies(key, spec) and isinstance(entry, dict):
            names.update((entry.get('ros__parameters') or {}).keys())
    return names


def ros_value(value):
    """Format a parameter value for `-p name:=value` (YAML syntax)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(ros_value(v) for v in value) + ']'
    return str(value)


class Launcher:
    """Own the child processes of one graph run and stop them cleanly."""

    def __init__(self, nodes, out_dir, domain_id, extra_param_file=None, node_parameters=None,
                 realtime=False):
        self._nodes = nodes
        self._realtime = realtime
        self._log_dir = Path(out_dir) / 'logs'
        self._domain_id = domain_id
        self._extra_param_file = extra_param_file
        self._node_parameters = node_parameters or {}
        self._user_parameters = load_yaml(extra_param_file) if extra_param_file else {}
        self._processes = {}
        self._log_files = []
        self.stop_requested = False

    def environment(self):
        """Return the children's environment: isolated domain, localhost discovery, command key."""
        env = dict(os.environ)
        env[COMMAND_KEY_VARIABLE] = launch_key()
        env['ROS_DOMAIN_ID'] = str(self._domain_id)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
        env.setdefault('AMENT_PREFIX_PATH', sys.prefix)
        env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
        env['PYTHONUNBUFFERED'] = '1'
        return env

    def start(self):
        """Start every node of the table."""
        self._log_dir.mkdir(parents=True, exist_ok=True)
        env = self.environment()
        for spec in self._nodes:
            log_file = open(self._log_dir / f'{spec.label}.log', 'w')
            self._log_files.append(log_file)
            node_env = env
            if self._realtime and spec.realtime_priority:
                node_env = dict(env, **{REALTIME_PRIORITY_VARIABLE: str(spec.realtime_priority)})
            self._processes[spec.label] = subprocess.Popen(
                self.command(spec), stdout=log_file, stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL, env=node_env, preexec_fn=_die_with_parent)

    def command(self, spec):
        """Return the argv of one node: table values, this run's values, the user's file."""
        ros_arguments = []
        user_values = user_parameter_names(self._user_parameters, spec)
        for name, value in self._node_parameters.get(spec.name, {}).items():
            if name not in user_values:
                ros_arguments += ['-p', f'{name}:={ros_value(value)}']
        if self._extra_param_file:
            ros_arguments += ['--params-file', str(self._extra_param_file)]
        return node_command(spec, ros_arguments, skip=user_values)

    def poll(self):
        """Return {label: exit code} of the children that have exited."""
        return {label: process.returncode for label, process in self._processes.items()
                if process.poll() is not None}

    def stop(self):
        """SIGINT every child, SIGKILL what is left after the grace period; return exit codes."""
        for process in self._processes.values():
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + STOP_GRACE_PERIOD
        for process in self._processes.values():
            try:
                process.wait(timeout=max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        for log_file in self._log_files:
            log_file.close()
        return {label: process.returncode for label, process in self._processes.items()}

    @property
    def pids(self):
        """Return the child process ids."""
        return [process.pid for process in self._processes.values()]


def start_recorder(out_dir, env, scenario=None):
    """
    Start bag_record into OUT/bag.mcap and wait until its subscriptions exist (--record).

    Returns the process; the graph starts afterwards. The scenario file, if any, is stored in
    the bag's metadata. Like every output in OUT, the bag replaces the previous run's; its log
    times are the graph's sim time.
    """
    log_path = Path(out_dir) / 'logs' / 'bag_record.log'
    log_path.parent.mkdir(parents=True, exist_ok=True)
    with open(log_path, 'w') as log_file:
        process = subprocess.Popen(
            executable_command('bag_record')
            + ['-o', str(Path(out_dir) / 'bag.mcap'), '--overwrite', '--use-sim-time']
            + ([] if scenario is None else ['--metadata', f'scenario={scenario}']),
            stdout=log_file, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env,
            preexec_fn=_die_with_parent)
    deadline = time.monotonic() + RECORDER_STARTUP_TIMEOUT
    while 'recording' not in log_path.read_text() and time.monotonic() < deadline:
        if process.poll() is not None:
            break
        time.sleep(POLL_PERIOD)
    return process


def stop_recorder(process):
    """SIGINT the recorder (it writes the bag's summary), SIGKILL it after the grace period."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        return process.wait(timeout=STOP_GRACE_PERIOD)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.wait()


def parse_arguments(argv=None):
    """Parse the launcher's command line."""
    parser = argparse.ArgumentParser(
        prog='dual_arm_bringup', description=__doc__.split('\n')[1],
        epilog='exit codes: 0 success, 1 task failed, 2 bad input, 3 a node died or timed out, '
               '130 interrupted')
    parser.add_argument('--scenario',
                        help='scenario YAML, or the name of a shipped one (config/scenarios); '
                             'runs one episode and exits (without: run until stopped)')
    parser.add_argument('--out', type=Path, default=Path('runs/latest'),
                        help='output directory for logs, metrics.json and plots')
    parser.add_argument('--mode', choices=('lockstep', 'realtime'), default='lockstep')
    parser.add_argument('--params', type=Path,
                        help='ROS parameter YAML (ros__parameters per node) applied last')
    parser.add_argument('--graph', choices=sorted(GRAPHS), default='full',
                        help='which node table to start')
    parser.add_argument('--domain-id', type=int,
                        help='ROS_DOMAIN_ID for the graph (default: one reserved for the run)')
    parser.add_argument('--timeout', type=float, default=600.0,
                        help='wall-clock limit of an episode [s]')
    parser.add_argument('--record', action='store_true',
                        help='record the graph topics into OUT/bag.mcap, replacing the previous '
                             "run's (bag_record on sim time, started before the nodes)")
    return parser.parse_args(argv)


def input_problems(args):
    """Return the problems of the scenario, parameter file and options (empty: all valid)."""
    problems = []
    if args.scenario is not None:
        try:
            load_scenario(args.scenario)
        except ConfigError as error:
            shipped = ', '.join(sorted(p.stem for p in config_path('scenarios').glob('*.yaml')))
            problems.append(f'scenario: {error}' + ('' if args.scenario.is_file() else
                                                    f' (shipped scenarios: {shipped})'))
    if args.params is not None:
        problems += parameter_file_problems(args.params, GRAPHS[args.graph]())
    if args.timeout <= 0.0:
        problems.append(f'--timeout must be > 0 s, got {args.timeout}')
    if args.domain_id is not None and not 0 <= args.domain_id <= MAX_DOMAIN_ID:
        problems.append(f'--domain-id must be in [0, {MAX_DOMAIN_ID}], got {args.domain_id}')
    return problems


class PhaseEcho:
    """Print the phase changes a node logs (lines with PHASE_LOG_PREFIX) as they appear."""

    def __init__(self, log_path):
        self._path = log_path
        self._offset = 0

    def poll(self):
        """Print the phase lines written since the last poll."""
        try:
            with open(self._path) as log:
                log.seek(self._offset)
                text = log.read()
        except OSError:
            return
        complete, _, _ = text.rpartition('\n')
        self._offset += len(complete) + (1 if complete else 0)
        for line in complete.splitlines():
            if PHASE_LOG_PREFIX in line:
                print(f'  {line[line.index(PHASE_LOG_PREFIX):]}', flush=True)


def log_tail(path, lines=LOG_TAIL_LINES):
    """Return the last lines of a log file, indented, or a note that there is none."""
    try:
        text = Path(path).read_text().strip().splitlines()
    except OSError:
        return '    (no log)'
    return '\n'.join(f'    {line}' for line in text[-lines:]) or '    (empty log)'


def main(argv=None):
    """Run the launcher; return the process exit code."""
    args = parse_arguments(argv)
    if args.scenario is not None:
        args.scenario = scenario_path(args.scenario).resolve()
    problems = input_problems(args)
    if problems:
        for problem in problems:
            print(f'dual_arm_bringup: {problem}', file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.domain_id is not None:
        return run(args, args.domain_id)
    with domain_id() as reserved:
        return run(args, reserved)


def run(args, domain):
    """Run the graph in ROS domain `domain`; return the exit code."""
    args.out.mkdir(parents=True, exist_ok=True)
    trajectory_log = (args.out / 'trajectory.npz').resolve() if args.scenario else None
    launcher = Launcher(GRAPHS[args.graph](), args.out, domain, args.params,
                        run_parameters(args.graph, args.scenario, args.mode, trajectory_log,
                                       args.record), realtime=args.mode == 'realtime')

    def request_stop(signum, frame):
        launcher.stop_requested = True

    signal.signal(signal.SIGINT, request_stop)
    signal.signal(signal.SIGTERM, request_stop)
    print(f'dual_arm_bringup: ROS_DOMAIN_ID={domain}, {args.mode} mode, logs in '
          f'{args.out / "logs"}', flush=True)
    recorder = (start_recorder(args.out, launcher.environment(), args.scenario)
                if args.record else None)
    if recorder is not None and recorder.poll() is not None:
        print(f'dual_arm_bringup: bag_record exited ({recorder.returncode}):\n'
              f'{log_tail(args.out / "logs" / "bag_record.log")}', file=sys.stderr)
        return EXIT_NODE_FAILED
    launcher.start()
    status = supervise(args, launcher)
    launcher.stop()
    if recorder is not None and stop_recorder(recorder) != 0:
        print(f'dual_arm_bringup: bag_record failed:\n'
              f'{log_tail(args.out / "logs" / "bag_record.log")}', file=sys.stderr)
        status = status or EXIT_NODE_FAILED
    if status != EXIT_SUCCESS or args.scenario is None:
        return status
    return _write_results(args)


def supervise(args, launcher):
    """Wait for the episode's end, a dead node, the timeout or a stop; return the exit code."""
    started = time.monotonic()
    phases = PhaseEcho(args.out / 'logs' / 'ds_motion_generator.log')
    while True:
        phases.poll()
        exited = launcher.poll()
        if launcher.stop_requested:
            print('dual_arm_bringup: stop requested, shutting the graph down')
            return EXIT_INTERRUPTED if args.scenario is not None else EXIT_SUCCESS
        if exited.get('sim_bridge') == 0:
            phases.poll()
            return EXIT_SUCCESS
        if exited:
            for label, code in sorted(exited.items()):
                print(f'dual_arm_bringup: node {label} exited with code {code}; stopping the '
                      f'graph. Last lines of its log:\n'
                      f'{log_tail(args.out / "logs" / f"{label}.log")}', file=sys.stderr)
            return EXIT_NODE_FAILED
        if args.scenario is not None and time.monotonic() - started > args.timeout:
            print(f'dual_arm_bringup: the episode exceeded {args.timeout:g} s of wall time; '
                  'stopping the graph', file=sys.stderr)
            return EXIT_NODE_FAILED
        time.sleep(POLL_PERIOD)


def _write_results(args):
    """Compute metrics and plots from the bridge's ground-truth log; return the exit code."""
    from dual_arm_control.evaluation.episode import (clock_stall_note, evaluate_episode,
                                                     metrics_summary)
    try:
        log = (args.out / 'logs' / 'ds_motion_generator.log').read_text()
    except OSError:
        log = ''
    try:
        metrics = evaluate_episode(args.scenario, args.out / 'trajectory.npz', args.out,
                                   graph=args.graph, events=phase_log_events(log))
    except (ConfigError, OSError, KeyError, ValueError) as error:
        print(f'dual_arm_bringup: cannot evaluate the episode: {error}', file=sys.stderr)
        return EXIT_NODE_FAILED
    (args.out / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
    print('dual_arm_bringup: metrics (all in metrics.json)')
    print(metrics_summary(metrics))
    if metrics.get('cycle_stalls'):
        print(f'dual_arm_bringup: {clock_stall_note(metrics)}')
    if metrics.get('success'):
        print('dual_arm_bringup: episode succeeded')
        return EXIT_SUCCESS
    print('dual_arm_bringup: the episode did not meet its task criteria (see metrics.json)',
          file=sys.stderr)
    return EXIT_TASK_FAILED


if __name__ == '__main__':
    sys.exit(main())
