"""The held box read from the pads' kinematics, its offset following the tracker slowly."""

from conftest import yaw_rotation
from dual_arm_control.core.held_object import HeldObjectEstimate
import numpy as np
import pytest

DT = 0.005                       # [s] DS tick
TAU = 0.1                        # [s] the offset's time constant (the default)
PAD_VELOCITY = np.array([0.8, 0.0, 0.4])
TRUE_OFFSET = np.array([0.0, 0.004, -0.002])


def run(estimate, ticks, noise, offset=lambda tick: TRUE_OFFSET):
    """Carry the box at PAD_VELOCITY; return the (p, v, true p) of every tick."""
    rows = []
    for tick in range(ticks):
        midpoint = np.array([0.5, 0.0, 0.35]) + PAD_VELOCITY * tick * DT
        true_position = midpoint + offset(tick)
        p, v = estimate.update(midpoint, np.eye(3), true_position + noise[tick],
                               PAD_VELOCITY + 0.3, DT, TAU)
        rows.append((p, v, true_position))
    return rows


def test_the_first_tick_of_a_hold_is_the_trackers_estimate():
    estimate = HeldObjectEstimate()
    p, v = estimate.update(np.zeros(3), np.eye(3), np.array([0.1, 0.2, 0.3]),
                           np.array([1.0, 0.0, 0.0]), DT, TAU)
    assert p == pytest.approx([0.1, 0.2, 0.3]) and v == pytest.approx([1.0, 0.0, 0.0])


def test_two_millimetres_of_mocap_noise_become_a_fraction_and_the_velocity_exact():
    """
    Mocap noise of 2 mm per coordinate at 200 Hz: the estimate is within 1 mm, its velocity exact.

    After 3 time constants a first-order filter of tau = 0.1 s over 5 ms ticks passes
    sqrt(dt / 2 tau) = 16 % of the noise (0.3 mm); the velocity is the pads', not the
    tracker's (off by 0.3 m/s here).
    """
    noise = np.random.default_rng(0).normal(0.0, 0.002, (200, 3))
    rows = run(HeldObjectEstimate(), 200, noise)
    errors = np.array([p - true for p, _, true in rows[60:]])
    assert np.abs(errors).max() < 0.001
    assert np.abs(noise[60:]).max() > 0.005
    for _, v, _ in rows[1:]:
        assert v == pytest.approx(PAD_VELOCITY)


def test_a_slip_of_the_box_in_the_pads_shows_up_within_a_few_time_constants():
    """The box slides 5 mm in the pads at tick 100: 95 % of it is in the estimate 3 tau later."""
    def slipped(tick):
        return TRUE_OFFSET + (np.array([0.0, 0.0, -0.005]) if tick >= 100 else 0.0)

    rows = run(HeldObjectEstimate(), 200, np.zeros((200, 3)), slipped)
    p, _, true = rows[100 + 60]
    assert abs((p - true)[2]) < 0.05 * 0.005
    p, _, true = rows[101]
    assert abs((p - true)[2]) > 0.9 * 0.005


def test_reset_starts_a_new_hold_from_the_tracker():
    estimate = HeldObjectEstimate()
    run(estimate, 10, np.zeros((10, 3)))
    estimate.reset()
    p, _ = estimate.update(np.zeros(3), np.eye(3), np.array([1.0, 1.0, 1.0]), np.zeros(3), DT,
                           TAU)
    assert p == pytest.approx([1.0, 1.0, 1.0])


def test_an_offset_grasp_turning_with_the_pads_moves_the_centre_around_them():
    """
    A box held 8 cm off centre, the grasp turning at 0.5 rad/s: its centre moves around the pads.

    Its centre 8 cm from the pads' midpoint along pad x, the grasp turning about z: the centre
    moves at omega x r = 0.04 m/s across, which the midpoint alone misses.
    """
    estimate = HeldObjectEstimate()
    rate, lever = 0.5, np.array([0.08, 0.0, 0.0])
    for tick in range(40):
        R = yaw_rotation(rate * tick * DT)
        p, v = estimate.update(np.zeros(3), R, R @ lever, np.zeros(3), DT, TAU)
    assert p == pytest.approx(R @ lever, abs=1e-9)
    assert v == pytest.approx(np.cross([0.0, 0.0, rate], R @ lever), abs=2e-3)


def test_the_velocity_of_an_accelerating_grasp_is_the_current_one_not_half_a_tick_old():
    """Pads accelerating at 10 m/s^2 (the toss): the estimate reads a t, not a (t - dt / 2)."""
    estimate = HeldObjectEstimate()
    acceleration = np.array([10.0, 0.0, 5.0])
    for tick in range(10):
        t = tick * DT
        p, v = estimate.update(0.5 * acceleration * t ** 2, np.eye(3), np.zeros(3),
                               np.zeros(3), DT, TAU)
    assert v == pytest.approx(acceleration * t, rel=1e-9)


def test_a_hold_starts_where_the_grasp_plan_puts_the_centre_not_at_a_lagging_estimate():
    """After the impact the tracker lags (7 mm seen); the planned offset starts the hold."""
    estimate = HeldObjectEstimate()
    planned = np.array([-0.05, 0.0, 0.01])
    lagging = np.array([0.4, 0.0, 0.3]) + planned - np.array([0.007, 0.0, 0.0])
    p, _ = estimate.update(np.array([0.4, 0.0, 0.3]), np.eye(3), lagging, np.zeros(3), DT, TAU,
                           planned_offset=planned)
    assert p == pytest.approx(np.array([0.4, 0.0, 0.3]) + planned)


def test_pads_rocking_in_opposite_senses_leave_the_grip_turning_with_the_box():
    """
    Both pads rock 15 deg on their faces' edges in opposite senses while the box turns by 10 deg.

    The grip's rotation is the box's turn to 1e-9 (the mean of +15 and -15 deg), and the centre
    of a box held 9 cm off it stays within 0.1 mm; a single pad's frame would put it
    9 cm x 2 sin(7.5 deg) = 2.3 cm away.
    """
    estimate = HeldObjectEstimate()
    R_left, R_right = yaw_rotation(0.3) @ np.diag([1.0, -1.0, -1.0]), np.diag([1.0, 1.0, 1.0])
    lever = np.array([-0.09, 0.0, 0.01])
    for tick in range(40):
        box_turn = yaw_rotation(np.radians(10.0) * tick / 39)
        rock = np.radians(15.0) * tick / 39
        grip = estimate.grip_rotation(box_turn @ yaw_rotation(rock) @ R_left,
                                      box_turn @ yaw_rotation(-rock) @ R_right)
        p, _ = estimate.update(np.zeros(3), grip, box_turn @ lever, np.zeros(3), DT, TAU,
                               planned_offset=lever if tick == 0 else None)
    assert grip == pytest.approx(box_turn @ R_left, abs=1e-9)
    assert np.linalg.norm(p - box_turn @ lever) < 1e-4
    single_pad = box_turn @ yaw_rotation(rock) @ lever
    assert np.linalg.norm(single_pad - box_turn @ lever) > 0.02


def carry_with_sample_ages(ages, read_ages):
    """
    Carry the box at PAD_VELOCITY, each tick's joint sample taken ages[tick] s before the tick.

    read_ages: the sample ages the estimate is told. Return the (p, v, true p at the tick) rows.
    """
    estimate, rows = HeldObjectEstimate(), []
    for tick, (age, read_age) in enumerate(zip(ages, read_ages)):
        midpoint = np.array([0.5, 0.0, 0.35]) + PAD_VELOCITY * (tick * DT - age)
        true_position = np.array([0.5, 0.0, 0.35]) + PAD_VELOCITY * tick * DT + TRUE_OFFSET
        p, v = estimate.update(midpoint, np.eye(3), true_position, PAD_VELOCITY, DT, TAU,
                               sample_age=read_age)
        rows.append((p, v, true_position))
    return rows


def test_joint_samples_taken_off_the_tick_give_the_pads_velocity_and_the_ticks_position():
    """
    In realtime a tick reads joint samples a cycle or two (2-4 ms) before or after it.

    Differenced between the samples' times the velocity is exact and the centre is carried to the
    tick; differenced over the 5 ms tick (ages not told) the speed is off by up to 4 ms / 5 ms.
    """
    drawn = np.random.default_rng(3).choice([-0.002, 0.0, 0.002, 0.004], 60)
    sample_times = np.maximum.accumulate(np.arange(60) * DT - drawn)
    ages = np.arange(60) * DT - sample_times
    for p, v, true_position in carry_with_sample_ages(ages, ages)[1:]:
        assert v == pytest.approx(PAD_VELOCITY, rel=1e-9)
        assert p == pytest.approx(true_position, abs=1e-9)
    unaware = carry_with_sample_ages(ages, np.zeros(60))
    speed_errors = [np.linalg.norm(v) / np.linalg.norm(PAD_VELOCITY) - 1 for _, v, _ in unaware]
    assert max(np.abs(speed_errors)) > 0.5 and np.any(np.diff(sample_times) == 0.0)


def test_a_joint_sample_read_at_two_ticks_keeps_the_velocity():
    """A stall delivers no new joint state between two ticks: no difference, no zero speed."""
    ages = [0.0, 0.0, 0.005, 0.0, 0.0]
    rows = carry_with_sample_ages(ages, ages)
    assert np.all(np.isfinite([v for _, v, _ in rows]))
    for p, v, true_position in rows[1:]:
        assert v == pytest.approx(PAD_VELOCITY, rel=1e-9)
        assert p == pytest.approx(true_position, abs=1e-9)
