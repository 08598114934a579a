"""
ds_motion_generator: phases, coordinated modulated DS, orientation and object DS (eqs. 1-9).

Feeds every FRI cycle's joint states and FT readings of both arms and the newest object estimate
to the runtime MotionGeneratorStep; on DS ticks (200 Hz on the cycle stamps) it publishes,
stamped with the tick, per-arm DS commands, the desired object twist, the phase and (every
MARKER_PERIOD) markers. With `lockstep` a tick waits for both arms' joint states and F/T readings
and the tracker's estimate, all stamped with it (other cycles only advance the schedule); in
realtime each left joint state triggers a cycle with the newest of the others (take-latest), and
with release_latency_lead the toss release leads by how late the commands act on the arms: the
DS command lag the controllers report on /diagnostics (runtime.command_latency).
Parameters: the whole MotionGeneratorConfig tree (live), plus the scenario, auto-start time,
landing target, controller timeout and rates. The stamps of both controllers' torque commands
tell it they are alive; one silent for controller_timeout halts the task (MotionGeneratorStep).
Services start an episode, send the arms home and reset. A new landing_target, set as a
parameter or as a point on /dual_arm/landing_target (frame world), re-plans the toss's release
state for it, or is refused with the reason. With a conveyor in the scenario the tracker's
container estimate (/container/state) is one more tick input, and the toss aims at the
container (runtime.motion_step).
"""

import re
import sys

from diagnostic_msgs.msg import DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.contract import ARMS, joint_names
from dual_arm_control.description.cell import arm_model, load_cell
from dual_arm_control.nodes.command_signature import command_key, signed
from dual_arm_control.nodes.diagnostics import CounterDiagnostics, refusal_logger
from dual_arm_control.nodes.markers import motion_markers
from dual_arm_control.nodes.messages import (arm_command_message, fill_twist, joint_state_of,
                                             LatestMessage, object_state_of, phase_message,
                                             stamp_ns, time_msg, wrench_of)
from dual_arm_control.nodes.process import create_topic_publisher, run_node
from dual_arm_control.parameters import ConfigParameters, NodeParameters
from dual_arm_control.runtime.command_latency import CommandLatency
from dual_arm_control.runtime.configuration import (motion_config_for_cell,
                                                    motion_config_for_scenario, planned_landing)
from dual_arm_control.runtime.controller_step import DS_COMMAND_LAG_KEY
from dual_arm_control.runtime.inputs import ArrivalBarrier
from dual_arm_control.runtime.motion_step import MotionGeneratorStep
from dual_arm_control.runtime.node_settings import node_table
from dual_arm_control.runtime.timing import seconds_to_ns
from dual_arm_control.scenario import load_scenario
import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

MARKER_PERIOD = 0.05
# Start of the log line of a phase change (the launcher echoes these as progress).
PHASE_LOG_PREFIX = 'phase at '
_PHASE_LOG_LINE = re.compile(re.escape(PHASE_LOG_PREFIX) + r'(?P<time>[0-9.]+) s: (?P<phase>\w+)'
                             r'(?: \[(?P<events>[^\]]*)\])?: (?P<reason>.*)$')
TICK_INPUTS = frozenset(('object', *(f'{arm}_{kind}' for arm in ARMS
                                     for kind in ('joints', 'ft'))))
CYCLE_TRIGGER = frozenset(('left_joints',))


def phase_log_line(time, phase, events, reason):
    """Return the log line of a phase change: time [s], phase name, events, reason."""
    listed = f' [{", ".join(events)}]' if events else ''
    return f'{PHASE_LOG_PREFIX}{time:.3f} s: {phase}{listed}: {reason}'


def phase_log_events(text):
    """Return [(time [s], events tuple, reason)] of the phase lines in a node log's text."""
    found = []
    for line in text.splitlines():
        match = _PHASE_LOG_LINE.search(line)
        if match:
            events = tuple(match['events'].split(', ')) if match['events'] else ()
            found.append((float(match['time']), events, match['reason']))
    return found


class DsMotionGenerator(Node):
    """The motion generator node: one MotionGeneratorStep driven by the FRI cycle stamps."""

    def __init__(self, node_name='ds_motion_generator', **node_options):
        super().__init__(node_name, **node_options)
        self._command_key = command_key()
        cell = load_cell()
        self._scenario = None
        self._defaults = {}
        settings = NodeParameters(
            self, node_table('ds_motion_generator').settings,
            defaults=lambda values: self._scenario_defaults(values, cell),
            extra_problem=self._landing_target_problem, on_change=self._on_setting)
        self._landing_target = np.asarray(settings['landing_target'], dtype=float)
        base = (motion_config_for_cell(cell) if self._scenario is None
                else motion_config_for_scenario(self._scenario, cell))
        parameters = ConfigParameters(self, base, self._on_config)
        self.step = MotionGeneratorStep(
            parameters.config, {arm: arm_model(arm, cell) for arm in ARMS},
            settings['ds_period'], seconds_to_ns(settings['auto_start_time']),
            refusal_logger(self.get_logger()), settings['controller_timeout'])
        # Lockstep: a cycle waits for all its inputs (and, on ticks, the estimate stamped with
        # it). Realtime: take-latest, the left joint state triggers the cycle.
        lockstep = settings['lockstep']
        conveyor = parameters.config.conveyor.enabled
        tick_inputs = TICK_INPUTS | ({'container'} if conveyor else set())
        if lockstep:
            self._barrier = ArrivalBarrier(
                lambda t: tick_inputs if self.step.is_new_tick(t) else CYCLE_TRIGGER)
        else:
            self._barrier = ArrivalBarrier(lambda t: CYCLE_TRIGGER)
        self._latency = (CommandLatency() if settings['release_latency_lead'] and not lockstep
                         else None)
        refuse = self.step.refusals.refuse
        self._inputs = {name: LatestMessage(object_state_of, name, refuse)
                        for name in ('object', 'container')}
        for arm in ARMS:
            self._inputs[f'{arm}_joints'] = LatestMessage(
                lambda msg, names=joint_names(arm): joint_state_of(msg, names), f'{arm}_joints',
                refuse)
            self._inputs[f'{arm}_ft'] = LatestMessage(wrench_of, f'{arm}_ft', refuse)
        self._last_marker_ns = None
        self._last_logged_ns = None
        self._diagnostics = CounterDiagnostics(self)
        self._command_pubs = {arm: create_topic_publisher(self, contract.DS_COMMAND, arm)
                              for arm in ARMS}
        self._twist_pub = create_topic_publisher(self, contract.OBJECT_DESIRED_TWIST)
        self._twist_msg = contract.OBJECT_DESIRED_TWIST.msg_type()
        self._twist_msg.header.frame_id = contract.WORLD_FRAME
        self._phase_pub = create_topic_publisher(self, contract.PHASE)
        self._marker_pub = create_topic_publisher(self, contract.MARKERS)
        for arm in ARMS:
            self.create_subscription(
                contract.JOINT_STATES.msg_type, contract.JOINT_STATES.resolved(arm),
                lambda msg, arm=arm: self._on_input(f'{arm}_joints', msg),
                contract.JOINT_STATES.subscription_qos(lockstep))
            self.create_subscription(
                contract.FT_WRENCH.msg_type, contract.FT_WRENCH.resolved(arm),
                lambda msg, arm=arm: self._on_input(f'{arm}_ft', msg),
                contract.FT_WRENCH.subscription_qos(lockstep))
            # The controllers' torque commands: only their stamps, as a sign of life.
            self.create_subscription(
                contract.TORQUE_COMMAND.msg_type, contract.TORQUE_COMMAND.resolved(arm),
                lambda msg, arm=arm: self._on_torque_command(arm, msg),
                contract.TORQUE_COMMAND.subscription_qos(lockstep))
        self.create_subscription(contract.OBJECT_STATE.msg_type, contract.OBJECT_STATE.name,
                                 lambda msg: self._on_input('object', msg),
                                 contract.OBJECT_STATE.subscription_qos(lockstep))
        if conveyor:
            self.create_subscription(contract.CONTAINER_STATE.msg_type,
                                     contract.CONTAINER_STATE.name,
                                     lambda msg: self._on_input('container', msg),
                                     contract.CONTAINER_STATE.subscription_qos(lockstep))
        if self._latency is not None:
            self.create_subscription(contract.DIAGNOSTICS.msg_type, contract.DIAGNOSTICS.name,
                                     self._on_diagnostics, contract.DIAGNOSTICS.qos)
        self.create_subscription(contract.LANDING_TARGET.msg_type, contract.LANDING_TARGET.name,
                                 self._on_landing_target, contract.LANDING_TARGET.qos)
        for service, command in ((contract.START_EPISODE_SERVICE, 'start'),
                                 (contract.GO_HOME_SERVICE, 'go_home'),
                                 (contract.RESET_EPISODE_SERVICE, 'reset')):
            self.create_service(Trigger, service, lambda request, response, command=command:
                                self._on_command(command, response))
        config = parameters.config
        self.get_logger().info(
            f'ds_motion_generator up: task {config.task.value}, impact speed '
            f'{config.impact.impact_speed:g} m/s, toss speed {config.toss.toss_speed:g} m/s, '
            f'auto start at {settings["auto_start_time"]:g} s (0 = start service), '
            f'{len(parameters.names)} tunable parameters')

    def _on_config(self, config):
        self.step.reconfigure(config)

    def _scenario_defaults(self, values, cell):
        """Return the defaults the scenario gives (where its toss lands), computed once."""
        if not values.get('scenario'):
            return {}
        if self._scenario is None:
            self._scenario = load_scenario(values['scenario'], cell=cell)
            landing = planned_landing(self._scenario, cell)
            self._defaults = {} if landing is None else {
                'landing_target': [float(v) for v in landing]}
        return self._defaults

    def _landing_target_problem(self, values):
        """Re-plan the release for a new landing_target; return why it is refused, or None."""
        target = np.asarray(values['landing_target'], dtype=float)
        if getattr(self, 'step', None) is None or np.array_equal(target, self._landing_target):
            return None
        return self.step.set_landing_target(target) or None

    def _on_setting(self, name, value):
        if name != 'landing_target':
            return
        self._landing_target = np.asarray(value, dtype=float)
        toss = self.step.pending_config.toss
        self.get_logger().info(
            f'landing target {np.round(self._landing_target, 3).tolist()} m: release at '
            f'{np.round(toss.release_position, 3).tolist()} m, {toss.toss_speed:.2f} m/s')

    def _on_landing_target(self, msg):
        target = np.array([msg.point.x, msg.point.y, msg.point.z])
        if msg.header.frame_id not in ('', contract.WORLD_FRAME) or not np.all(
                np.isfinite(target)):
            self.step.refusals.refuse(
                'landing_target', f'landing target {target.tolist()} in frame '
                f'{msg.header.frame_id!r} refused: finite coordinates in '
                f'{contract.WORLD_FRAME!r} expected')
            return
        self.set_parameters([Parameter('landing_target', value=target.tolist())])

    def _on_torque_command(self, arm, msg):
        stamp = stamp_ns(msg.header.stamp)
        if self._command_key is None or signed(self._command_key, stamp, msg.name, msg.effort,
                                               msg.header.frame_id):
            self.step.command_heard(arm, stamp)

    def _on_diagnostics(self, msg):
        for status in msg.status:
            for entry in status.values:
                if entry.key != DS_COMMAND_LAG_KEY:
                    continue
                try:
                    lag = float(entry.value) * 1e-3
                except ValueError:
                    lag = None
                if not self._latency.reported(status.name, lag):
                    self.step.refusals.refuse(
                        'diagnostics', f'{status.name}: {DS_COMMAND_LAG_KEY} = {entry.value!r} '
                        'refused: a finite lag >= 0 expected')
                self.step.command_latency = self._latency.seconds

    def _on_command(self, command, response):
        self.step.request(command)
        response.success = True
        response.message = f'{command} requested for the next DS tick'
        return response

    def _on_input(self, name, msg):
        self._inputs[name].offer(msg)
        self._run(self._barrier.arrived(stamp_ns(msg.header.stamp), name))

    def _run(self, stamps):
        for t_ns in stamps:
            joints = {arm: self._inputs[f'{arm}_joints'].value() for arm in ARMS}
            ft = {arm: self._inputs[f'{arm}_ft'].value() for arm in ARMS}
            if None in joints.values() or None in ft.values():
                continue
            tick = self.step.cycle(t_ns, joints, ft, self._inputs['object'].value(),
                                   self._inputs['container'].value())
            if tick is not None:
                self._publish(tick)

    def _publish(self, tick):
        if tick.phase.reason and tick.stamp_ns != self._last_logged_ns:
            self._last_logged_ns = tick.stamp_ns
            self.get_logger().info(phase_log_line(tick.stamp_ns * 1e-9, tick.phase.phase.value,
                                                  tick.phase.events, tick.phase.reason))
        for arm in ARMS:
            self._command_pubs[arm].publish(arm_command_message(arm, tick.commands[arm]))
        fill_twist(self._twist_msg, tick.desired_twist)
        self._twist_pub.publish(self._twist_msg)
        self._phase_pub.publish(phase_message(tick.phase))
        if tick.output is not None and (
                self._last_marker_ns is None or not 0 <= tick.stamp_ns - self._last_marker_ns
                < seconds_to_ns(MARKER_PERIOD)):
            self._last_marker_ns = tick.stamp_ns
            self._marker_pub.publish(motion_markers(time_msg(tick.stamp_ns), tick.output))
        self._diagnostics.publish_if_due(tick.stamp_ns, self._report)

    def _report(self):
        refusals = self.step.refusals
        level = (DiagnosticStatus.WARN if refusals.total or self.step.controllers.lost_arms
                 else DiagnosticStatus.OK)
        values = dict(refusals.counts, phase=self.step.phase.value, refused_total=refusals.total,
                      time_resets=self.step.time_resets, dropped_stamps=self._barrier.dropped,
                      lost_controllers=','.join(self.step.controllers.lost_arms))
        if self._latency is not None:
            values['command_latency_ms'] = round(self._latency.seconds * 1e3, 3)
        return level, f'phase {self.step.phase.value}', values


def main(args=None):
    """Run the ds_motion_generator node."""
    return run_node(DsMotionGenerator, 'ds_motion_generator', args)


if __name__ == '__main__':
    sys.exit(main())
