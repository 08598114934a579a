"""
A node SIGKILLed under dual_arm_bringup itself: the launcher must exit 3 naming the node.

Trial i kills the node number i of the product graph's table (bridge, tracker, DS, wrench QP,
the controllers, cell_state_publisher) at the trial's first contact, in a recorded lockstep run.
The launcher then stops the other nodes and the recorder; the bag up to the kill must read whole
(bag_info: complete).
"""

import os
from pathlib import Path
import signal
import subprocess
import sys

from dual_arm_control.benchmarks.graph_bench import child_pids
from dual_arm_control.bringup import EXIT_NODE_FAILED
from dual_arm_control.graph import full_graph
from dual_arm_control.tools.faults.graph_run import SimProbe
from dual_arm_control.tools.faults.outcome import bag_status, TrialOutcome

LAUNCHER_TIMEOUT = 300.0


def _node_pid(launcher_pid, spec):
    """Return the pid of the launcher's child running the node of spec, or None."""
    for pid in child_pids(launcher_pid):
        try:
            cmdline = Path(f'/proc/{pid}/cmdline').read_text().replace('\0', ' ')
        except OSError:
            continue
        if f'__node:={spec.name}' in cmdline and (
                not spec.namespace or f'__ns:={spec.namespace}' in cmdline):
            return pid
    return None


def kill_under_launcher(kind, trial):
    """Run the trial under dual_arm_bringup --record, kill one node at the first contact."""
    spec = full_graph()[trial.index % len(full_graph())]
    t_kill = trial.stage_time('impact') or 1.0
    outcome = TrialOutcome(kind, trial.index, trial.seed, fault_time=t_kill,
                           note=f'killed {spec.label}')
    out = Path(trial.out_dir)
    command = [sys.executable, '-m', 'dual_arm_control.bringup', '--scenario',
               str(trial.scenario_file()), '--out', str(out), '--domain-id', str(trial.domain),
               '--record']
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, stdin=subprocess.DEVNULL)
    try:
        probe = SimProbe(trial.domain, 'fault_clock_watch')
        try:
            probe.spin_until(lambda: probe.clock_ns * 1e-9 >= t_kill or process.poll() is not None,
                             LAUNCHER_TIMEOUT)
        finally:
            probe.close()
        pid = _node_pid(process.pid, spec)
        if pid is not None and process.poll() is None:
            os.kill(pid, signal.SIGKILL)
        stdout, stderr = process.communicate(timeout=LAUNCHER_TIMEOUT)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    (out / 'bringup.log').write_text(stdout + stderr)
    outcome.exit_code = process.returncode
    named = f'node {spec.label} exited' in stderr
    outcome.bag_status = bag_status(out / 'bag.mcap')
    outcome.held = bool(outcome.exit_code == EXIT_NODE_FAILED and named
                        and outcome.bag_status == 'complete')
    if not named:
        outcome.note += '; the launcher did not name it'
    return outcome
