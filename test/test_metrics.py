"""Episode metrics on synthetic trajectories with known answers."""

from conftest import SOURCE_ROOT
from dual_arm_control.core.geometry import matrix_to_quat_xyzw, rotation_exp
from dual_arm_control.evaluation import metrics
from dual_arm_control.evaluation.episode import METRIC_KEYS
import numpy as np
import pytest

DT = 0.002


def test_energy_of_known_torque_velocity_profile():
    t = np.arange(0.0, 1.0 + DT / 2, DT)
    tau = np.zeros((t.size, 7))
    dq = np.zeros((t.size, 7))
    tau[:, 0] = 10.0
    dq[:, 0] = np.sin(np.pi * t)
    tau[:, 3] = -4.0
    dq[:, 3] = -0.5
    expected = 10.0 * 2.0 / np.pi + 2.0
    assert metrics.mechanical_energy(t, tau, dq) == pytest.approx(expected, rel=1e-5)


def test_energy_is_the_power_of_the_whole_arm():
    t = np.arange(0.0, 1.0 + DT / 2, DT)
    tau = np.zeros((t.size, 7))
    dq = np.zeros((t.size, 7))
    tau[:, 1], dq[:, 1] = 3.0, 1.0
    tau[:, 2], dq[:, 2] = 3.0, -1.0
    assert metrics.mechanical_energy(t, tau, dq) == pytest.approx(0.0, abs=1e-12)


def test_energy_counts_braking_as_spent():
    t = np.arange(0.0, 1.0 + DT / 2, DT)
    tau = np.full((t.size, 7), 2.0)
    dq = np.full((t.size, 7), -1.0)
    assert metrics.mechanical_energy(t, tau, dq) == pytest.approx(14.0, rel=1e-9)


def test_contact_instants_and_impact_speed():
    t = np.arange(0.0, 1.0, DT)
    left = t >= 0.400
    right = t >= 0.406
    velocity = np.zeros((t.size, 3))
    velocity[:, 1] = -0.5
    velocity[t >= 0.4, 1] = -0.1
    left_index = metrics.first_true_index(left)
    right_index = metrics.first_true_index(right)
    assert t[left_index] == pytest.approx(0.400)
    assert t[right_index] - t[left_index] == pytest.approx(0.006)
    assert metrics.impact_speed(velocity, left_index) == pytest.approx(0.5)
    assert metrics.impact_speed(velocity, left_index, [0.0, -1.0, 0.0]) == pytest.approx(0.5)
    assert metrics.impact_speed(velocity, left_index, [1.0, 0.0, 0.0]) == pytest.approx(0.0)
    assert metrics.impact_speed(velocity, None) is None


def test_grasp_needs_sustained_contact_and_release_needs_both_pads_off():
    t = np.arange(0.0, 2.0, DT)
    left = (t >= 0.3) & (t < 1.2)
    right = ((t >= 0.3) & (t < 0.31)) | ((t >= 0.4) & (t < 1.25))
    grasp, release = metrics.grasp_and_release_indices(t, left, right)
    assert t[grasp] == pytest.approx(0.4)
    assert t[release] == pytest.approx(1.25)


def test_grasp_segments_follow_each_grasp_to_its_release():
    t = np.arange(0.0, 4.0, DT)
    left = ((t >= 0.3) & (t < 1.2)) | ((t >= 2.0) & (t < 3.0))
    right = ((t >= 0.3) & (t < 1.2)) | ((t >= 2.01) & (t < 3.5))
    segments = metrics.grasp_segments(t, left, right)
    assert [(t[grasp], t[release]) for grasp, release in segments] == [
        pytest.approx((0.3, 1.2)), pytest.approx((2.01, 3.5))]
    assert metrics.grasp_segments(t, left, np.zeros_like(left)) == []


def test_a_regrasp_is_judged_by_its_worse_grasp():
    """A place that grasps twice (contacts 1, then 6 cycles apart) reports the 6."""
    from dual_arm_control.description.cell import load_cell
    from dual_arm_control.evaluation.episode import episode_metrics
    from dual_arm_control.scenario import load_scenario
    data = synthetic_grasp_log(100, 101, samples=1200)
    index = np.arange(1200)
    data['left_pad_contact'] = ((index >= 100) & (index < 400)) | (index >= 700)
    data['right_pad_contact'] = ((index >= 101) & (index < 400)) | (index >= 706)
    result = episode_metrics(load_scenario('paper_place'), data, load_cell())
    assert result['grasp_count'] == 2
    assert result['contact_time_gap'] == round(6 * DT, 9)
    assert result['t_grasp'] == pytest.approx(101 * DT)


def test_no_release_while_one_pad_still_holds():
    t = np.arange(0.0, 2.0, DT)
    left = t >= 0.3
    right = (t >= 0.3) & (t < 1.0)
    grasp, release = metrics.grasp_and_release_indices(t, left, right)
    assert grasp is not None and release is None


def test_slip_is_measured_in_the_object_frame():
    t = np.arange(0.0, 1.0, DT)
    n = t.size
    object_position = np.column_stack((0.4 + 0.5 * t, np.zeros(n), 0.3 + 0.2 * t))
    quats = np.array([matrix_to_quat_xyzw(rotation_exp([0.0, 0.0, 1.5 * s])) for s in t])
    offset_object = np.array([0.0, 0.1, 0.0])
    tool = np.array([object_position[i] + rotation_exp([0.0, 0.0, 1.5 * t[i]]) @ offset_object
                     for i in range(n)])
    no_slip = metrics.max_pad_slip(tool, object_position, quats, 0, n)
    assert no_slip == pytest.approx(0.0, abs=1e-12)
    slipping = tool.copy()
    slipping[:, 2] -= 0.02 * t
    slip = metrics.max_pad_slip(slipping, object_position, quats, 0, n)
    assert slip == pytest.approx(0.02 * t[-1], rel=1e-9)
    # A pad settling 1 cm onto its face (along the face normal, object y) does not slide on it.
    seating = tool - np.array([rotation_exp([0.0, 0.0, 1.5 * t[i]]) @ [0.0, 0.01 * t[i], 0.0]
                               for i in range(n)])
    assert metrics.max_pad_slip(seating, object_position, quats, 0, n) == \
        pytest.approx(0.0, abs=1e-12)


def test_landing_on_the_surface_below():
    t = np.arange(0.0, 1.0, DT)
    v0 = np.array([1.0, 0.0, 1.0])
    p0 = np.array([0.7, 0.0, 0.7])
    position = p0 + np.outer(t, v0) + np.outer(0.5 * t ** 2, [0.0, 0.0, -9.81])

    def table(x, y):
        return 0.15 if x > 0.62 else 0.0

    index = metrics.landing_index(t, position, 0, 0.1, table)
    flight_time = (1.0 + np.sqrt(1.0 + 2.0 * 9.81 * (0.7 - 0.25 - 0.005))) / 9.81
    assert t[index] == pytest.approx(flight_time, abs=DT)


def test_return_home_and_velocity_error():
    t = np.arange(0.0, 2.0, DT)
    excursion = np.where(t < 1.0, 0.3 * np.sin(np.pi * t), 0.0)
    tool = np.column_stack((excursion, np.zeros_like(t), np.zeros_like(t)))
    index = metrics.return_home_index(t, [tool, tool], metrics.first_true_index(t > 0.5))
    assert t[index] == pytest.approx(1.0 - np.arcsin(0.1) / np.pi, abs=DT)
    assert metrics.relative_velocity_error([0.9, 0.0, 0.9], [1.0, 0.0, 1.0]) == pytest.approx(0.1)


def test_criteria_refuse_out_of_range_values():
    with pytest.raises(ValueError, match='grasp_hold_time'):
        metrics.EventCriteria(grasp_hold_time=-1.0)


def synthetic_grasp_log(left_contact_index, right_contact_index, samples=1000):
    """Return a trajectory log at rest where each pad touches from its index on."""
    from dual_arm_control.trajectory_log import ARM_FIELDS, OBJECT_FIELDS
    t = 0.3 + DT * np.arange(samples)
    data = {'t': t}
    for name in OBJECT_FIELDS:
        data[name] = np.zeros((samples, 4 if name == 'object_quat_xyzw' else 3))
    data['object_quat_xyzw'][:, 3] = 1.0
    for arm, first in (('left', left_contact_index), ('right', right_contact_index)):
        for name in ARM_FIELDS:
            data[f'{arm}_{name}'] = np.zeros((samples, 7 if name in ('q', 'dq', 'tau') else 3))
        data[f'{arm}_pad_contact'] = np.arange(samples) >= first
        data[f'{arm}_pad_force'] = np.zeros((samples, 3))
    return data


@pytest.mark.parametrize('cycles_apart, within_limit', [(5, True), (6, False)])
def test_contact_gap_of_whole_cycles_is_exact(cycles_apart, within_limit):
    """5 FRI cycles apart is 10 ms exactly (not 0.010000000000000009) and meets the limit."""
    from dual_arm_control.description.cell import load_cell
    from dual_arm_control.evaluation.episode import CONTACT_GAP_LIMIT, episode_metrics
    from dual_arm_control.scenario import load_scenario
    data = synthetic_grasp_log(562, 562 + cycles_apart)
    result = episode_metrics(load_scenario('paper_toss'), data, load_cell())
    assert result['contact_time_gap'] == round(cycles_apart * DT, 9)
    assert (result['contact_time_gap'] <= CONTACT_GAP_LIMIT) == within_limit
    assert result['t_grasp'] is not None
    assert 'landing_prediction_error' in result and result['landing_prediction_error'] is None


def test_joint_speed_ratio_finds_the_joint_and_the_time_above_its_limit():
    t = np.arange(0.0, 1.0, 0.002)
    dq = np.zeros((t.size, 7))
    limits = np.array([1.71, 1.71, 1.75, 2.27, 2.44, 3.14, 3.14])
    dq[:, 3] = 3.0 * limits[3] * np.sin(np.pi * t)
    dq[:, 0] = 0.9 * limits[0]
    ratio, time_above, joint = metrics.joint_speed_ratio(t, dq, limits)
    assert ratio == pytest.approx(3.0, rel=1e-4)
    assert joint == 3
    # 3 sin(pi t) > 1 on t in (asin(1/3) / pi, 1 - asin(1/3) / pi): 0.784 s.
    assert time_above == pytest.approx(1.0 - 2.0 * np.arcsin(1.0 / 3.0) / np.pi, abs=0.004)
    assert metrics.joint_speed_ratio(t, 0.5 * dq, 3.0 * limits)[1] == 0.0


def test_the_readme_documents_every_metric_key():
    """metrics.json keys (METRIC_KEYS) and the README's metrics contract must agree."""
    readme = (SOURCE_ROOT / 'README.md').read_text()
    contract = readme[readme.index('## Metrics contract'):readme.index('## Layout')]
    assert [key for key in METRIC_KEYS if f'`{key}`' not in contract] == []


@pytest.mark.parametrize('flight_time', [-0.004, 0.0, 0.002, 0.008])
def test_release_state_is_taken_where_the_flight_crosses_the_release_plane(flight_time):
    """A sample of the planned parabola, before or after the plane, maps back to the plan."""
    gravity = 9.81
    p_planned, v_planned = np.array([0.68, 0.0, 0.45]), np.array([0.76, 0.1, 0.38])
    across = np.cross(v_planned, [0.0, 0.0, 1.0])
    lateral = 0.005 * across / np.linalg.norm(across)
    acceleration = np.array([0.0, 0.0, -gravity])
    p_sample = (p_planned + lateral + v_planned * flight_time
                + 0.5 * acceleration * flight_time ** 2)
    v_sample = v_planned + acceleration * flight_time
    p_plane, v_plane = metrics.release_state_on_plane(p_sample, v_sample, p_planned, v_planned,
                                                      gravity)
    assert (p_plane - p_planned) @ v_planned == pytest.approx(0.0, abs=1e-12)
    assert np.linalg.norm(p_plane - p_planned) == pytest.approx(0.005, abs=1e-9)
    assert metrics.direction_error_degrees(v_plane, v_planned) < 0.01
    assert abs(metrics.relative_speed_error(v_plane, v_planned)) < 1e-4
    assert metrics.direction_error_degrees(v_sample, v_planned) > 0.5 * abs(flight_time) * 1000


def test_a_flight_that_never_reaches_the_release_plane_keeps_its_sample():
    """Straight down across a steep plane that the fall never reaches: the sample as it is."""
    p_sample, v_sample = np.array([0.5, 0.0, 0.4]), np.array([0.0, 0.0, -1.0])
    p_plane, v_plane = metrics.release_state_on_plane(
        p_sample, v_sample, np.array([0.6, 0.0, 0.4]), np.array([1.0, 0.0, 0.0]), 9.81)
    assert np.array_equal(p_plane, p_sample) and np.array_equal(v_plane, v_sample)
