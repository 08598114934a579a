"""Task phase machine on synthetic input trajectories sampled at 200 Hz and 500 Hz."""

from dataclasses import replace

from dual_arm_control.core.contact import ContactGeometry, ContactState
from dual_arm_control.core.exceptions import ConfigError, InputError
from dual_arm_control.core.phases import (
    Phase, PhaseConfig, PhaseInputs, PhaseMachine, Task)
import numpy as np
import pytest

RATES_DT = (0.005, 0.002)
P_OBJECT_START = np.array([0.6, 0.0, 0.2])
V_RELEASE = np.array([1.0, 0.0, 0.0])
P_RELEASE = P_OBJECT_START + 0.3 * V_RELEASE
P_PLACE = np.array([0.6, 0.3, 0.2])
P_LIFT = P_OBJECT_START + np.array([0.0, 0.0, 0.2])
STANDBY_LEFT = np.array([0.3, 0.4, 0.5])
STANDBY_RIGHT = np.array([0.3, -0.4, 0.5])
AWAY = np.array([0.1, 0.0, 0.0])


def contact(in_contact):
    """Return a ContactState with the given contact flag (force and geometry agree)."""
    return ContactState(in_contact=in_contact, force_contact=in_contact,
                        normal_force=20.0 if in_contact else 0.0,
                        geometry=ContactGeometry(0.0, (0.0, 0.0), True))


class Scenario:
    """
    A synthetic episode as functions of time t (s); times are the expected transitions.

    start at 0.10 s (held for 20 ms), left pad in contact from 0.50 s, right from 0.52 s, the
    object moves from 0.60 s (see object_state), both pads free from contact_end, tools at their
    standby positions from home_time, go_home held from go_home_time.
    """

    def __init__(self, contact_end=0.95, home_time=1.3, go_home_time=None,
                 object_state=None, left_contact_start=0.50, right_contact_start=0.52,
                 start_until=0.12):
        self.contact_end = contact_end
        self.home_time = home_time
        self.go_home_time = go_home_time
        self.object_state = object_state or toss_object_state
        self.left_contact_start = left_contact_start
        self.right_contact_start = right_contact_start
        self.start_until = start_until

    def inputs(self, t, episode_start=0.0):
        t_episode = t - episode_start
        away = AWAY if t_episode < self.home_time else np.zeros(3)
        p_world_object, v_world_object = self.object_state(t_episode)
        go_home = self.go_home_time is not None and t_episode >= self.go_home_time
        return PhaseInputs(
            p_world_tool_left=STANDBY_LEFT + away, p_world_tool_right=STANDBY_RIGHT + away,
            p_world_object=p_world_object, v_world_object=v_world_object,
            contact_left=contact(self.left_contact_start <= t_episode < self.contact_end),
            contact_right=contact(self.right_contact_start <= t_episode < self.contact_end),
            p_world_release=P_RELEASE, v_world_release=V_RELEASE, p_world_place=P_PLACE,
            p_world_lift=P_LIFT, p_world_standby_left=STANDBY_LEFT,
            p_world_standby_right=STANDBY_RIGHT,
            start_episode=0.10 <= t_episode < self.start_until, go_home=go_home)


def toss_object_state(t, lateral=np.zeros(3)):
    """Object at rest until 0.6 s, then at 1 m/s along the release velocity (+x)."""
    moving = max(t - 0.6, 0.0)
    velocity = V_RELEASE if t > 0.6 else np.zeros(3)
    return P_OBJECT_START + lateral + moving * V_RELEASE, velocity


def place_object_state(t, target=P_PLACE):
    """Object converging to target (the place), distance 0.3 exp(-(t - 0.6) / 0.1) m."""
    direction = (target - P_OBJECT_START) / np.linalg.norm(target - P_OBJECT_START)
    if t <= 0.6:
        return P_OBJECT_START.copy(), np.zeros(3)
    distance = 0.3 * np.exp(-(t - 0.6) / 0.1)
    return target - distance * direction, distance / 0.1 * direction


def lift_object_state(t):
    """Object rising 0.2 m with distance to the lift pose 0.2 exp(-(t - 0.6) / 0.1) m."""
    if t <= 0.6:
        return P_OBJECT_START.copy(), np.zeros(3)
    distance = 0.2 * np.exp(-(t - 0.6) / 0.1)
    return P_LIFT - np.array([0.0, 0.0, distance]), np.array([0.0, 0.0, distance / 0.1])


def run(machine, scenario, dt, duration, episode_start=0.0, t_start=0.0):
    """Step the machine; return the list of (time, output) for every update."""
    record = []
    steps = int(round(duration / dt))
    for k in range(1, steps + 1):
        t = t_start + k * dt
        record.append((t, machine.update(scenario.inputs(t, episode_start), dt)))
    return record


def transitions(record):
    return [(t, out.transition) for t, out in record if out.transition is not None]


def assert_sequence(record, expected, dt):
    """Each transition (target phase, expected time) happens within one period after it."""
    found = transitions(record)
    assert [tr.target for _, tr in found] == [phase for phase, _ in expected], found
    for (t, transition), (_, expected_time) in zip(found, expected):
        assert expected_time - 1e-9 <= t < expected_time + dt + 1e-9, (transition, t)


LEAD = PhaseConfig().release_lead_time
TOSS_SEQUENCE = [(Phase.REACH, 0.10), (Phase.CONTACT, 0.52), (Phase.MANIPULATE, 0.57),
                 (Phase.RELEASE, 0.90 - LEAD), (Phase.RETRACT, 0.95), (Phase.STANDBY, 1.30)]


@pytest.mark.parametrize('dt', RATES_DT)
@pytest.mark.parametrize('task', [Task.PICK_AND_TOSS, Task.TOSS_TO_TARGET, Task.PLACE_TOSS])
def test_toss_tasks_full_sequence(task, dt):
    """Release when the object is a lead time from the release plane (1 m/s: at 0.90 s)."""
    machine = PhaseMachine(PhaseConfig(), task)
    record = run(machine, Scenario(), dt, 1.5)
    assert_sequence(record, TOSS_SEQUENCE, dt)
    release = [tr for _, tr in transitions(record) if tr.target is Phase.RELEASE][0]
    assert 'reaches the release plane 0.000 m' in release.reason
    events = [e for _, out in record for e in out.events]
    for name in ('episode_started', 'contact_left', 'contact_right', 'grasp_settled',
                 'released', 'hands_open', 'home', 'contact_lost_left', 'contact_lost_right'):
        assert events.count(name) == 1, name
    assert all(out.task is task for _, out in record)


@pytest.mark.parametrize('dt', RATES_DT)
def test_pick_and_place_full_sequence(dt):
    """
    Release needs distance <= place_tolerance (0.012 m) AND speed < place_speed (0.1 m/s here).

    distance = 0.3 exp(-(t-0.6)/0.1), speed = distance / 0.1: the distance gate alone would
    pass at 0.6 + 0.1 ln 25 = 0.922 s (speed 0.12 m/s), both gates at 0.6 + 0.1 ln 30 = 0.940 s.
    """
    machine = PhaseMachine(PhaseConfig(place_speed=0.1, place_tolerance=0.012),
                           Task.PICK_AND_PLACE)
    record = run(machine, Scenario(object_state=place_object_state, contact_end=1.0), dt, 1.5)
    release_time = 0.6 + 0.1 * np.log(30.0)
    assert_sequence(record, [(Phase.REACH, 0.10), (Phase.CONTACT, 0.52),
                             (Phase.MANIPULATE, 0.57), (Phase.RELEASE, release_time),
                             (Phase.RETRACT, 1.0), (Phase.STANDBY, 1.30)], dt)


@pytest.mark.parametrize('dt', RATES_DT)
def test_pick_and_lift_holds_until_go_home(dt):
    """Lift never releases by itself; lift_reached at 0.6 + 0.1 ln(0.2 / 0.03) = 0.790 s."""
    machine = PhaseMachine(PhaseConfig(), Task.PICK_AND_LIFT)
    scenario = Scenario(object_state=lift_object_state, contact_end=3.05, go_home_time=3.0,
                        home_time=3.3)
    record = run(machine, scenario, dt, 3.5)
    assert_sequence(record, [(Phase.REACH, 0.10), (Phase.CONTACT, 0.52),
                             (Phase.MANIPULATE, 0.57), (Phase.RELEASE, 3.0),
                             (Phase.RETRACT, 3.05), (Phase.STANDBY, 3.3)], dt)
    lift_times = [t for t, out in record if 'lift_reached' in out.events]
    lift_expected = 0.6 + 0.1 * np.log(0.2 / 0.03)
    assert len(lift_times) == 1 and lift_expected <= lift_times[0] < lift_expected + dt
    release = [tr for _, tr in transitions(record) if tr.target is Phase.RELEASE][0]
    assert 'go_home' in release.reason


@pytest.mark.parametrize('dt', RATES_DT)
def test_release_on_crossing_the_plane_off_path(dt):
    """
    Object 0.05 m off the release path never comes within 0.03 m but crosses the plane.

    The plane through x_release normal to v_release is crossed at 0.6 + 0.3 = 0.9 s.
    """
    machine = PhaseMachine(PhaseConfig(release_lead_time=0.0))
    offset = np.array([0.0, 0.04, 0.03])
    scenario = Scenario(object_state=lambda t: toss_object_state(t, offset), contact_end=1.0)
    record = run(machine, scenario, dt, 1.5)
    found = transitions(record)
    release_time, release = [(t, tr) for t, tr in found if tr.target is Phase.RELEASE][0]
    assert 0.9 - 1e-9 <= release_time < 0.9 + dt + 1e-9
    assert 'reaches the release plane 0.050 m' in release.reason


@pytest.mark.parametrize('dt', RATES_DT)
@pytest.mark.parametrize('lead', [0.0, 0.003, 0.02])
def test_release_leads_the_plane_by_the_pads_opening_time(lead, dt):
    """At 1 m/s the plane is crossed at 0.9 s; the release comes lead earlier, on the tick."""
    machine = PhaseMachine(PhaseConfig(release_lead_time=lead))
    record = run(machine, Scenario(), dt, 1.5)
    release_time = [t for t, tr in transitions(record) if tr.target is Phase.RELEASE][0]
    assert 0.9 - lead - 1e-9 <= release_time < 0.9 - lead + dt + 1e-9


class LateCommands(Scenario):
    """The toss scenario whose commands act command_latency [s] after each update."""

    def __init__(self, command_latency, **kwargs):
        super().__init__(**kwargs)
        self.command_latency = command_latency

    def inputs(self, t, episode_start=0.0):
        return replace(super().inputs(t, episode_start), command_latency=self.command_latency)


@pytest.mark.parametrize('dt', RATES_DT)
@pytest.mark.parametrize('latency', [0.0, 0.002, 0.008, 0.015])
def test_release_leads_the_plane_by_the_command_latency_too(latency, dt):
    """A release command that acts latency late is decided lead + latency before the plane."""
    machine = PhaseMachine(PhaseConfig())
    record = run(machine, LateCommands(latency), dt, 1.5)
    release_time, release = [(t, tr) for t, tr in transitions(record)
                             if tr.target is Phase.RELEASE][0]
    expected = 0.9 - LEAD - latency
    assert expected - 1e-9 <= release_time < expected + dt + 1e-9
    assert ('ms early' in release.reason) == (latency > 0.0), release.reason


def noisy_toss_state(noise, speed):
    """Return a toss object_state at speed [m/s] whose positions carry noise[tick] (5 ms)."""
    def state(t):
        moving = max(t - 0.6, 0.0)
        velocity = speed * V_RELEASE if t > 0.6 else np.zeros(3)
        sample = noise[int(round(t / 0.005)) % len(noise)]
        return P_RELEASE - 0.3 * V_RELEASE + moving * speed * V_RELEASE + sample, velocity
    return state


@pytest.mark.parametrize('seed', range(20))
def test_position_noise_inside_the_sphere_does_not_release_before_the_plane(seed):
    """
    A box tracked with 2 mm of position noise at 0.8 m/s is let go at the plane, not before.

    It covers 4 mm a 5 ms tick, so two successive noisy distances to the release point grow
    now and then while it still approaches; the sphere's moving-away test reads the estimated
    velocity instead, so the plane rule releases it, within the noise and one tick of the
    crossing (0.6 + 0.3 / 0.8 s).
    """
    noise = np.random.default_rng(seed).normal(0.0, 0.002, (1000, 3))
    machine = PhaseMachine(PhaseConfig(release_lead_time=0.0))
    scenario = Scenario(object_state=noisy_toss_state(noise, 0.8), contact_end=2.0)
    record = run(machine, scenario, 0.005, 1.5)
    release_time, release = [(t, tr) for t, tr in transitions(record)
                             if tr.target is Phase.RELEASE][0]
    assert 'release plane' in release.reason
    assert abs(release_time - (0.6 + 0.3 / 0.8)) <= 0.0125


@pytest.mark.parametrize('offset', [np.array([0.0, 0.3, 0.0]), np.array([0.0, 0.0, -0.15])])
def test_no_release_when_object_far_from_release(offset):
    """0.3 m or 0.15 m off the path (> 0.10 m plane radius): the hands keep holding."""
    machine = PhaseMachine(PhaseConfig())
    scenario = Scenario(object_state=lambda t: toss_object_state(t, offset), contact_end=5.0)
    record = run(machine, scenario, 0.005, 2.0)
    assert record[-1][1].phase is Phase.MANIPULATE
    assert all('released' not in out.events for _, out in record)


def test_no_release_when_object_starts_past_the_plane_and_moves_away():
    machine = PhaseMachine(PhaseConfig())
    scenario = Scenario(object_state=lambda t: toss_object_state(t, 0.4 * V_RELEASE),
                        contact_end=5.0)
    record = run(machine, scenario, 0.005, 2.0)
    assert record[-1][1].phase is Phase.MANIPULATE


@pytest.mark.parametrize('dt', RATES_DT)
def test_second_episode_is_clean(dt):
    """
    After a full episode a second one repeats the same transitions, shifted by its start.

    A release flag latched forever would release at once in the
    second episode; here the release again happens at 0.90 s after the episode's origin. The
    start command is held high through the whole first episode: it must act only once.
    """
    machine = PhaseMachine(PhaseConfig())
    first = run(machine, Scenario(start_until=1.5), dt, 1.5)
    assert_sequence(first, TOSS_SEQUENCE, dt)
    second = run(machine, Scenario(), dt, 1.5, episode_start=1.5, t_start=1.5)
    shifted = [(phase, time + 1.5) for phase, time in TOSS_SEQUENCE]
    assert_sequence(second, shifted, dt)


def test_rate_independence_of_transition_times():
    """The same input trajectory at 200 Hz and 500 Hz: every transition within 5 ms."""
    times = {}
    for dt in RATES_DT:
        machine = PhaseMachine(PhaseConfig())
        times[dt] = [t for t, _ in transitions(run(machine, Scenario(), dt, 1.5))]
    assert len(times[0.005]) == len(times[0.002]) == 6
    assert np.max(np.abs(np.subtract(times[0.005], times[0.002]))) <= 0.005 + 1e-9


@pytest.mark.parametrize('dt', RATES_DT)
def test_time_in_phase(dt):
    """time_in_phase = t - (time the phase was entered), 0 on the entering update."""
    machine = PhaseMachine(PhaseConfig())
    entered = 0.0
    for t, out in run(machine, Scenario(), dt, 1.5):
        if out.transition is not None:
            entered = t
        assert out.time_in_phase == pytest.approx(t - entered, abs=1e-9)


@pytest.mark.parametrize('dt', RATES_DT)
def test_single_contact_is_reported_then_the_grasp_aborted(dt):
    """Left pad alone from 0.50 s, right pad never: reported at 0.70 s, aborted at 0.90 s."""
    machine = PhaseMachine(PhaseConfig())
    record = run(machine, Scenario(right_contact_start=10.0), dt, 1.5)
    reports = [t for t, out in record if 'single_contact_timeout_left' in out.events]
    assert len(reports) == 1 and 0.70 - 1e-9 <= reports[0] < 0.70 + dt + 1e-9
    aborts = [(t, out) for t, out in record if 'grasp_aborted' in out.events]
    assert len(aborts) == 1 and 0.90 - 1e-9 <= aborts[0][0] < 0.90 + dt + 1e-9
    transition = aborts[0][1].transition
    assert transition.target is Phase.RETRACT
    assert 'only the left pad touched' in transition.reason
    assert all(out.phase is not Phase.CONTACT for _, out in record)


def test_contact_lost_before_settling_returns_to_reach():
    machine = PhaseMachine(PhaseConfig(contact_settle_time=0.1))
    scenario = Scenario(contact_end=0.56)
    record = run(machine, scenario, 0.005, 0.7)
    targets = [tr.target for _, tr in transitions(record)]
    assert targets == [Phase.REACH, Phase.CONTACT, Phase.REACH]


def test_grasp_lost_during_manipulation_releases():
    """Right pad slips off at 0.65 s (object far from release): RELEASE after 0.1 s."""
    machine = PhaseMachine(PhaseConfig())

    class Slip(Scenario):
        def inputs(self, t, episode_start=0.0):
            inputs = super().inputs(t, episode_start)
            if t >= 0.65:
                return PhaseInputs(**{**inputs.__dict__, 'contact_right': contact(False)})
            return inputs

    record = run(machine, Slip(contact_end=5.0), 0.005, 1.0)
    release = [(t, out) for t, out in record
               if out.transition is not None and out.phase is Phase.RELEASE][0]
    assert 0.75 - 1e-9 <= release[0] < 0.755 + 1e-9
    assert 'grasp_lost' in release[1].events


def test_go_home_while_reaching_and_reset():
    machine = PhaseMachine(PhaseConfig())
    record = run(machine, Scenario(go_home_time=0.3, home_time=0.5), 0.005, 0.6)
    assert [tr.target for _, tr in transitions(record)] == [
        Phase.REACH, Phase.RETRACT, Phase.STANDBY]
    machine = PhaseMachine(PhaseConfig())
    run(machine, Scenario(), 0.005, 0.7)
    assert machine.phase is Phase.MANIPULATE
    inputs = Scenario().inputs(0.7)
    out = machine.update(PhaseInputs(**{**inputs.__dict__, 'reset': True}), 0.005)
    assert out.phase is Phase.STANDBY and out.transition.reason == 'reset command'


def test_task_selection_applies_from_next_episode():
    machine = PhaseMachine(PhaseConfig(), 'pick_and_toss')
    run(machine, Scenario(), 0.005, 0.3)
    machine.select_task(Task.PICK_AND_PLACE)
    assert machine.task is Task.PICK_AND_TOSS
    run(machine, Scenario(), 0.005, 1.2, t_start=0.3)
    assert machine.phase is Phase.STANDBY
    record = run(machine, Scenario(), 0.005, 0.2, episode_start=1.5, t_start=1.5)
    assert record[-1][1].task is Task.PICK_AND_PLACE
    with pytest.raises(ConfigError, match='unknown task'):
        machine.select_task('juggle')


def test_invalid_inputs_rejected():
    machine = PhaseMachine(PhaseConfig())
    inputs = Scenario().inputs(0.0)
    with pytest.raises(InputError):
        machine.update(inputs, 0.0)
    with pytest.raises(InputError):
        PhaseInputs(**{**inputs.__dict__, 'p_world_object': [0.0, np.nan, 0.0]})
    with pytest.raises(InputError):
        PhaseInputs(**{**inputs.__dict__, 'contact_left': True})
    for latency in (-0.001, np.nan, np.inf):
        with pytest.raises(InputError, match='command_latency'):
            replace(inputs, command_latency=latency)
    with pytest.raises(ConfigError):
        PhaseConfig(release_tolerance=0.0)
    with pytest.raises(ConfigError):
        PhaseConfig(contact_settle_time=-0.01)


def test_a_box_the_arms_bring_no_closer_than_2_cm_is_put_down_where_it_stalls():
    """
    2 cm above the place (outside the 1.2 cm tolerance) the box stops: released 0.3 s later.

    It slows below 0.02 m/s at 0.6 + 0.1 ln(0.3 / 0.002) = 1.101 s (within 3 cm since 0.894 s);
    the release comes place_stall_time after, on the tick; a box still converging is not.
    """
    machine = PhaseMachine(PhaseConfig(), Task.PICK_AND_PLACE)
    stall = P_PLACE + np.array([0.0, 0.0, 0.02])
    scenario = Scenario(object_state=lambda t: place_object_state(t, stall), contact_end=3.0)
    record = run(machine, scenario, 0.005, 2.0)
    release_time, release = [(t, tr) for t, tr in transitions(record)
                             if tr.target is Phase.RELEASE][0]
    slow = 0.6 + 0.1 * np.log(0.3 / 0.002)
    assert slow + 0.3 - 0.005 <= release_time <= slow + 0.3 + 0.005 + 1e-9
    assert 'stalled 0.020 m' in release.reason


@pytest.mark.parametrize('offset, released', [
    ((-0.04, 0.0, 0.004), True), ((0.0, 0.0, 0.04), False), ((-0.07, 0.0, 0.004), False)])
def test_a_box_resting_on_the_table_short_of_the_place_is_put_down(offset, released):
    """
    A box grasped forward of its centre can rest on the table 4 cm short of the place.

    It is let go place_stall_time after it stalls: within 5 cm horizontally and 3 cm in
    height. A box held 4 cm above the place, or resting 7 cm short, is not put down there.
    """
    machine = PhaseMachine(PhaseConfig(), Task.PICK_AND_PLACE)
    stall = P_PLACE + np.array(offset)
    scenario = Scenario(object_state=lambda t: place_object_state(t, stall), contact_end=3.0)
    record = run(machine, scenario, 0.005, 2.0)
    releases = [tr for _, tr in transitions(record) if tr.target is Phase.RELEASE]
    assert bool(releases) is released
    if released:
        assert 'stalled 0.040 m' in releases[0].reason
