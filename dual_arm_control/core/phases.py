"""
Task phase machine of the grab-and-toss task (paper section II, Fig. 2).

update(inputs, dt) advances the time in phase by dt seconds and takes at most one transition
(quantised to one update period whatever the rate); it returns a PhaseMachineOutput. Phases:

    STANDBY --start--> REACH --both pads in contact--> CONTACT --settled--> MANIPULATE
    REACH --one pad alone in contact for grasp_close_timeout--> RETRACT (grasp aborted)
    MANIPULATE --release condition--> RELEASE --pads free or open-hands time--> RETRACT
    RETRACT --both tools near standby--> STANDBY

go_home: REACH to RETRACT, CONTACT/MANIPULATE to RELEASE; reset: to STANDBY at once (rising edges).
"""

from dataclasses import dataclass, field
import enum

from dual_arm_control.core.contact import ContactState
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.release import PlaceRelease, TossRelease
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import finite_rows
import numpy as np


class Phase(enum.Enum):
    """Phases of one grab episode."""

    STANDBY = 'standby'
    REACH = 'reach'
    CONTACT = 'contact'
    MANIPULATE = 'manipulate'
    RELEASE = 'release'
    RETRACT = 'retract'


class Task(enum.Enum):
    """What to do with the object once grasped."""

    PICK_AND_TOSS = 'pick_and_toss'
    PICK_AND_PLACE = 'pick_and_place'
    PICK_AND_LIFT = 'pick_and_lift'
    PLACE_TOSS = 'place_toss'
    TOSS_TO_TARGET = 'toss_to_target'


TASK_NAMES = tuple(task.value for task in Task)
"""The tasks by name, as parameters and scenario files give them."""


def task_from_name(task):
    """Return the Task for a Task or its value ('pick_and_toss', ...); raise ConfigError."""
    try:
        return Task(task)
    except ValueError:
        choices = ', '.join(t.value for t in Task)
        raise ConfigError(f'unknown task {task!r}; expected one of {choices}') from None


@dataclass(frozen=True)
class PhaseConfig:
    """Thresholds of the phase machine (SI units)."""

    contact_settle_time: float = setting(
        0.05, 'Both pads must stay in contact this long in CONTACT.', unit='s', low=0)
    single_contact_timeout: float = setting(
        0.2, 'A lone pad in contact this long in REACH is reported.', unit='s', low=0,
        low_open=True)
    grasp_close_timeout: float = setting(
        0.4, 'One pad in contact alone this long in REACH aborts the grasp: RETRACT, event '
        "'grasp_aborted' (the other pad will not arrive in time).", unit='s', low=0, low_open=True)
    release_tolerance: float = setting(
        0.03, "The paper's 0.03 m: a box inside this sphere around x_release moving away from "
        'it is released.', unit='m', low=0, low_open=True)
    release_plane_radius: float = setting(
        0.10, 'A toss releases when the object reaches the plane through x_release across the '
        'release velocity within this of the release path.', unit='m', low=0, low_open=True)
    release_lead_time: float = setting(
        0.003, 'The release plane is reached this much early (object speed times it), for the '
        'time the pads take to come off the box: 3 ms puts the free flight on the planned '
        'parabola at the plane on average (0: 7 ms late, the box 2 percent fast and 1.3 deg '
        'steep).', unit='s', low=0, high=1.0)
    place_tolerance: float = setting(
        0.007, 'Place release when ||x_o - x_place|| <= this and the object is slower than '
        'place_speed (the place target lies 4 mm below the resting pose: at 0.012 m boxes were '
        'let go up to 6 mm above the table).', unit='m', low=0, low_open=True)
    place_speed: float = setting(
        0.015, 'Place release when ||v_o|| < this (and within place_tolerance): the table has '
        'stopped the box (at 0.05 boxes still descending 3 mm above it were let go and fell, '
        '0.07 m/s median as the pads left them, up to 0.102; at 0.1 the speeds piled up at '
        '0.097-0.100 m/s).', unit='m/s', low=0, low_open=True)
    place_stall_distance: float = setting(
        0.05, 'A box this near the place horizontally and within place_stall_height of its '
        'height, slower than place_stall_speed for place_stall_time, is let go where it is '
        '(core.release.PlaceRelease).', unit='m', low=0, high=1.0)
    place_stall_height: float = setting(0.03, 'See place_stall_distance.', unit='m', low=0,
                                        high=1.0)
    place_stall_speed: float = setting(0.02, 'See place_stall_distance.', unit='m/s', low=0,
                                       high=1.0, low_open=True)
    place_stall_time: float = setting(0.3, 'See place_stall_distance.', unit='s', low=0,
                                      high=10.0, low_open=True)
    lift_tolerance: float = setting(0.03, "'lift_reached' fires within this of the lift "
                                    'pose.', unit='m', low=0, low_open=True)
    grasp_loss_timeout: float = setting(0.1, 'A pad out of contact this long in MANIPULATE '
                                        'releases.', unit='s', low=0, low_open=True)
    open_hands_time: float = setting(
        0.5, 'RELEASE ends after this even if a pad still reads contact.',
        unit='s', low=0, low_open=True)
    home_tolerance: float = setting(
        0.03, 'RETRACT ends when both tools are this close to standby.',
        unit='m', low=0, low_open=True)

    def __post_init__(self):
        check_settings(self)


_VECTOR_FIELDS = ('p_world_tool_left', 'p_world_tool_right', 'p_world_object',
                  'v_world_object', 'p_world_release', 'v_world_release', 'p_world_place',
                  'p_world_lift', 'p_world_standby_left', 'p_world_standby_right')


@dataclass(frozen=True)
class PhaseInputs:
    """
    Everything the phase machine looks at in one update (world frame, SI units).

    Fields:
        p_world_tool_left, p_world_tool_right: (3,) m, tool origins.
        p_world_object, v_world_object: (3,) m and m/s, object position and velocity.
        contact_left, contact_right: ContactState of each arm (contact.py).
        p_world_release, v_world_release: (3,) m and m/s, desired release state (toss tasks).
        p_world_place: (3,) m, place position (PICK_AND_PLACE).
        p_world_lift: (3,) m, lift position (PICK_AND_LIFT).
        p_world_standby_left, p_world_standby_right: (3,) m, standby tool positions.
        start_episode, go_home, reset: commands, acting on their rising edge.
        command_latency: s (>= 0), how long after this update its command reaches the arms
            (realtime: the graph's transport); the toss release leads the plane by it too.

    """

    p_world_tool_left: np.ndarray
    p_world_tool_right: np.ndarray
    p_world_object: np.ndarray
    v_world_object: np.ndarray
    contact_left: ContactState
    contact_right: ContactState
    p_world_release: np.ndarray
    v_world_release: np.ndarray
    p_world_place: np.ndarray
    p_world_lift: np.ndarray
    p_world_standby_left: np.ndarray
    p_world_standby_right: np.ndarray
    start_episode: bool = False
    go_home: bool = False
    reset: bool = False
    command_latency: float = 0.0

    def __post_init__(self):
        if not (np.isfinite(self.command_latency) and self.command_latency >= 0.0):
            raise InputError(f'command_latency = {self.command_latency} s must be finite, >= 0')
        rows = finite_rows(_VECTOR_FIELDS, [getattr(self, name) for name in _VECTOR_FIELDS], 3)
        for name, row in zip(_VECTOR_FIELDS, rows):
            object.__setattr__(self, name, row)
        for name in ('contact_left', 'contact_right'):
            if not isinstance(getattr(self, name), ContactState):
                raise InputError(f'{name} must be a ContactState, got '
                                 f'{type(getattr(self, name)).__name__}')


@dataclass(frozen=True)
class PhaseTransition:
    """One phase change and why it happened."""

    source: Phase
    target: Phase
    reason: str


@dataclass(frozen=True)
class PhaseMachineOutput:
    """
    Result of one update.

    Fields:
        phase: phase after the update.
        task: task of the current episode.
        time_in_phase: s, time since the phase was entered (0 on the update that entered it).
        events: names of what happened in this update, e.g. 'contact_left', 'released'.
        transition: the PhaseTransition of this update, or None.

    """

    phase: Phase
    task: Task
    time_in_phase: float
    events: tuple = field(default_factory=tuple)
    transition: PhaseTransition = None


def _condition_duration(active, duration, dt):
    """Return how long a condition has held (s): None if inactive, 0 when first seen."""
    return None if not active else 0.0 if duration is None else duration + dt


class PhaseMachine:
    """The task phase machine; state is explicit and only changes in update()."""

    def __init__(self, config, task=Task.PICK_AND_TOSS):
        self._config = config
        self._pending_task = task_from_name(task)
        self._task = self._pending_task
        self._phase = Phase.STANDBY
        self._time_in_phase = 0.0
        self._previous_commands = {'start_episode': False, 'go_home': False, 'reset': False}
        self._previous_contact = {'left': False, 'right': False}
        self._clear_episode_latches()

    @property
    def phase(self):
        """Return the current Phase."""
        return self._phase

    @property
    def task(self):
        """Return the Task of the current (or next, in STANDBY) episode."""
        return self._task

    @property
    def time_in_phase(self):
        """Return the time [s] since the current phase was entered."""
        return self._time_in_phase

    def select_task(self, task):
        """Choose the task; it applies at once in STANDBY, else from the next episode."""
        self._pending_task = task_from_name(task)
        if self._phase is Phase.STANDBY:
            self._task = self._pending_task

    def _clear_episode_latches(self):
        self._single_contact_time = None
        self._single_contact_reported = False
        self._grasp_loss_time = None
        self._toss_release = TossRelease()
        self._place_release = PlaceRelease()
        self._lift_reached = False

    def update(self, inputs, dt):
        """
        Advance by dt seconds (> 0) on the given PhaseInputs; return a PhaseMachineOutput.

        The time in phase is advanced first, then the transition of the current phase is
        evaluated on the new inputs; a transition resets the time in phase to 0.
        """
        if not isinstance(inputs, PhaseInputs):
            raise InputError(f'inputs must be PhaseInputs, got {type(inputs).__name__}')
        dt = float(dt)
        if not np.isfinite(dt) or dt <= 0.0:
            raise InputError(f'dt = {dt:g} s must be finite and > 0')
        self._time_in_phase += dt
        commands = {name: bool(getattr(inputs, name)) and not self._previous_commands[name]
                    for name in self._previous_commands}
        self._previous_commands = {name: bool(getattr(inputs, name))
                                   for name in self._previous_commands}
        events = self._contact_events(inputs)
        transition = self._command_transition(commands, events)
        if transition is None:
            transition = self._phase_transition(inputs, dt, events)
        if transition is not None:
            self._phase = transition.target
            self._time_in_phase = 0.0
        return PhaseMachineOutput(self._phase, self._task, self._time_in_phase, tuple(events),
                                  transition)

    def _contact_events(self, inputs):
        events = []
        for arm, state in (('left', inputs.contact_left), ('right', inputs.contact_right)):
            if state.in_contact and not self._previous_contact[arm]:
                events.append(f'contact_{arm}')
            elif not state.in_contact and self._previous_contact[arm]:
                events.append(f'contact_lost_{arm}')
            self._previous_contact[arm] = state.in_contact
        return events

    def _command_transition(self, commands, events):
        phase = self._phase
        if commands['reset']:
            events.append('reset')
            self._clear_episode_latches()
            self._task = self._pending_task
            return PhaseTransition(phase, Phase.STANDBY, 'reset command')
        if commands['go_home'] and phase is not Phase.STANDBY:
            events.append('go_home')
            if phase is Phase.REACH:
                return PhaseTransition(phase, Phase.RETRACT, 'go_home command while reaching')
            if phase in (Phase.CONTACT, Phase.MANIPULATE):
                events.append('released')
                return PhaseTransition(phase, Phase.RELEASE,
                                       'go_home command while holding: open the hands first')
            return None
        if commands['start_episode'] and phase is Phase.STANDBY:
            self._clear_episode_latches()
            self._task = self._pending_task
            events.append('episode_started')
            return PhaseTransition(phase, Phase.REACH,
                                   f'start_episode command, task {self._task.value}')
        return None

    def _phase_transition(self, inputs, dt, events):
        handler = {Phase.STANDBY: None, Phase.REACH: self._from_reach,
                   Phase.CONTACT: self._from_contact, Phase.MANIPULATE: self._from_manipulate,
                   Phase.RELEASE: self._from_release, Phase.RETRACT: self._from_retract,
                   }[self._phase]
        return None if handler is None else handler(inputs, dt, events)

    def _from_reach(self, inputs, dt, events):
        left = inputs.contact_left.in_contact
        right = inputs.contact_right.in_contact
        if left and right:
            return PhaseTransition(Phase.REACH, Phase.CONTACT,
                                   'both pads in contact (force and geometry)')
        self._single_contact_time = _condition_duration(left != right,
                                                        self._single_contact_time, dt)
        if self._single_contact_time is None:
            self._single_contact_reported = False
        elif (self._single_contact_time >= self._config.single_contact_timeout - 1e-9
              and not self._single_contact_reported):
            self._single_contact_reported = True
            events.append(f"single_contact_timeout_{'left' if left else 'right'}")
        if (self._single_contact_time is not None
                and self._single_contact_time >= self._config.grasp_close_timeout - 1e-9):
            events.append('grasp_aborted')
            return PhaseTransition(
                Phase.REACH, Phase.RETRACT,
                f"grasp did not close: only the {'left' if left else 'right'} pad touched for "
                f'{self._single_contact_time:.3f} s')
        return None

    def _from_contact(self, inputs, dt, events):
        if not (inputs.contact_left.in_contact and inputs.contact_right.in_contact):
            return PhaseTransition(Phase.CONTACT, Phase.REACH,
                                   'contact lost before the grasp settled')
        if self._time_in_phase >= self._config.contact_settle_time - 1e-9:
            self._grasp_loss_time = None
            self._toss_release.reset()
            self._place_release.reset()
            events.append('grasp_settled')
            return PhaseTransition(Phase.CONTACT, Phase.MANIPULATE,
                                   f'both pads in contact for {self._time_in_phase:.3f} s')
        return None

    def _from_manipulate(self, inputs, dt, events):
        config = self._config
        holding = inputs.contact_left.in_contact and inputs.contact_right.in_contact
        self._grasp_loss_time = _condition_duration(not holding, self._grasp_loss_time, dt)
        if self._grasp_loss_time is not None:
            if self._grasp_loss_time >= config.grasp_loss_timeout - 1e-9:
                events.extend(('grasp_lost', 'released'))
                return PhaseTransition(Phase.MANIPULATE, Phase.RELEASE,
                                       f'a pad out of contact for {self._grasp_loss_time:.3f} s')
        if self._task is Task.PICK_AND_LIFT:
            distance = np.linalg.norm(inputs.p_world_object - inputs.p_world_lift)
            if distance <= config.lift_tolerance and not self._lift_reached:
                self._lift_reached = True
                events.append('lift_reached')
            return None
        reason = self._release_reason(inputs, dt)
        if reason is not None:
            events.append('released')
            return PhaseTransition(Phase.MANIPULATE, Phase.RELEASE, reason)
        return None

    def _release_reason(self, inputs, dt):
        """Return why the object must be released now (place or toss rule), or None."""
        if self._task is Task.PICK_AND_PLACE:
            return self._place_release.reason(inputs.p_world_object, inputs.v_world_object,
                                              inputs.p_world_place, self._config, dt)
        return self._toss_release.reason(inputs.p_world_object, inputs.v_world_object,
                                         inputs.p_world_release, inputs.v_world_release,
                                         self._config, inputs.command_latency)

    def _from_release(self, inputs, dt, events):
        if not (inputs.contact_left.in_contact or inputs.contact_right.in_contact):
            events.append('hands_open')
            return PhaseTransition(Phase.RELEASE, Phase.RETRACT, 'both pads out of contact')
        if self._time_in_phase >= self._config.open_hands_time - 1e-9:
            events.append('hands_open')
            return PhaseTransition(Phase.RELEASE, Phase.RETRACT,
                                   f'hands opened for {self._time_in_phase:.3f} s')
        return None

    def _from_retract(self, inputs, dt, events):
        tolerance = self._config.home_tolerance
        left = np.linalg.norm(inputs.p_world_tool_left - inputs.p_world_standby_left)
        right = np.linalg.norm(inputs.p_world_tool_right - inputs.p_world_standby_right)
        if left <= tolerance and right <= tolerance:
            events.append('home')
            return PhaseTransition(Phase.RETRACT, Phase.STANDBY,
                                   f'tools {left:.3f} m and {right:.3f} m from standby')
        return None
