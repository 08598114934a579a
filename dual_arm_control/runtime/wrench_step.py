"""
The wrench QP role: the contact wrench of each pad, once per DS tick (core WrenchDistributor).

tick() gets the tick's phase and desired object twist (from the motion generator), both arms'
joint positions and the newest object estimate; the tool poses come from the arms' models and
the estimate is predicted to the tick. The wrenches are zero outside CONTACT / MANIPULATE,
before the first phase, joint state or object estimate, and when the QP fails (counted;
last_result keeps the distributor's report of the last tick, status included). The
same tick again gets the same answer without touching the filters. A new distributor config
applies at the next tick; a new object mass or size at the next tick outside a grasp.
"""

from dual_arm_control.core.arms import ARMS
from dual_arm_control.core.wrench_distribution import GRASPING_PHASES, WrenchDistributor
from dual_arm_control.runtime.node_settings import DS_PERIOD
from dual_arm_control.runtime.signals import WrenchSample
from dual_arm_control.runtime.timing import estimate_at, TickSchedule
import numpy as np

COUNTERS = ('ticks', 'repeated_answers', 'grasp_ticks', 'infeasible_ticks',
            'ticks_without_object_state', 'ticks_without_joint_states', 'ticks_without_phase',
            'object_changes_applied')


class WrenchStep:
    """The wrench QP role; config: WrenchDistributorConfig; models: {arm: ArmModel}."""

    def __init__(self, config, object_mass, object_size, models):
        self._config = config
        self._models = models
        self.object_mass = float(object_mass)
        self.object_size = tuple(float(s) for s in object_size)
        self._distributor = WrenchDistributor(config, self.object_mass, self.object_size)
        self._pending_config = None
        self._pending_object = None
        self._schedule = TickSchedule(DS_PERIOD)
        self._last = None
        self.last_result = None
        self.counters = dict.fromkeys(COUNTERS, 0)

    @property
    def config(self):
        """Return the WrenchDistributorConfig in use."""
        return self._config

    def reconfigure(self, config):
        """Use config from the next tick on."""
        self._pending_config = config

    def change_object(self, mass=None, size=None):
        """Use a new object mass [kg] and/or size (3,) [m] from the next tick outside a grasp."""
        pending_mass, pending_size = self._pending_object or (self.object_mass,
                                                              self.object_size)
        self._pending_object = (pending_mass if mass is None else float(mass),
                                pending_size if size is None else tuple(map(float, size)))

    def tick(self, stamp_ns, phase, desired_twist, joint_positions, estimate):
        """
        Return {arm: WrenchSample} of the tick stamp_ns.

        phase: core Phase or None; desired_twist: TwistSample or None; joint_positions
        {arm: (7,)} (an arm missing if none arrived yet); estimate: newest ObjectState or None.
        """
        if self._last is not None and stamp_ns == self._schedule.last_tick_ns:
            self.counters['repeated_answers'] += 1
            return self._last
        self.counters['ticks'] += 1
        self.last_result = None
        dt = self._schedule.take(stamp_ns)
        if self._pending_config is not None:
            self._config, self._pending_config = self._pending_config, None
            self._distributor.reconfigure(self._config)
        if self._pending_object is not None and phase not in GRASPING_PHASES:
            self.object_mass, self.object_size = self._pending_object
            self._pending_object = None
            self._distributor = WrenchDistributor(self._config, self.object_mass,
                                                  self.object_size)
            self.counters['object_changes_applied'] += 1
        wrenches = self._wrenches(stamp_ns, phase, desired_twist, joint_positions, estimate, dt)
        self._last = {arm: WrenchSample(stamp_ns, wrenches[arm]) for arm in ARMS}
        return self._last

    def _wrenches(self, stamp_ns, phase, desired_twist, joint_positions, estimate, dt):
        zeros = {arm: np.zeros(6) for arm in ARMS}
        if phase is None:
            self.counters['ticks_without_phase'] += 1
            return zeros
        if any(arm not in joint_positions for arm in ARMS):
            self.counters['ticks_without_joint_states'] += 1
            return zeros
        if estimate is None or not estimate.valid:
            self.counters['ticks_without_object_state'] += 1
            return zeros
        if desired_twist is None:
            v_desired, w_desired = np.zeros(3), np.zeros(3)
        else:
            v_desired, w_desired = desired_twist.linear, desired_twist.angular
        p_tools, R_tools = {}, {}
        for arm in ARMS:
            p_tools[arm], R_tools[arm] = self._models[arm].tool_pose(joint_positions[arm])
        p_object, R_object, v_object, w_object = estimate_at(estimate, stamp_ns)
        result = self._distributor.step(phase, p_tools, R_tools, p_object, R_object, v_object,
                                        w_object, v_desired, w_desired, dt)
        self.last_result = result
        if phase in GRASPING_PHASES:
            self.counters['grasp_ticks'] += 1
            if not result.feasible:
                self.counters['infeasible_ticks'] += 1
        return result.wrenches
