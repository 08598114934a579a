"""
The DS gives the same reach at 200 Hz and 500 Hz; the nodes tick on the FRI grid.

The tools follow the commands kinematically, integrated at 0.5 ms with each command held until
the next tick (as the torque-controlled arms do), from standby toward the paper's cube.
"""

from dual_arm_control.contract import ARMS
from dual_arm_control.core.geometry import rotation_exp
from dual_arm_control.core.motion_generator import DualArmMotionGenerator
from dual_arm_control.core.motion_signals import ArmMeasurement, ObjectMeasurement
from dual_arm_control.description.cell import load_cell
from dual_arm_control.runtime.configuration import motion_config_for_scenario
from dual_arm_control.runtime.timing import TickSchedule
from dual_arm_control.scenario import load_scenario, scenario_path
import numpy as np

PLANT_STEP = 0.0005
START = 0.3
DURATION = 1.8


def reach(ds_period, outputs=None):
    """
    Return ({arm: (n, 3) tool path}, (n,) times, [(time, phase)]) of one reach.

    outputs, a list, receives every tick's MotionOutput.
    """
    cell = load_cell()
    scenario = load_scenario(scenario_path('paper_toss'), cell=cell)
    generator = DualArmMotionGenerator(motion_config_for_scenario(scenario, cell))
    position = {arm: np.array(cell.arm(arm).standby_position) for arm in ARMS}
    rotation = {arm: np.array(cell.arm(arm).R_world_standby) for arm in ARMS}
    obj = ObjectMeasurement(np.array(scenario.object.position), np.eye(3), np.zeros(3))
    paths = {arm: [] for arm in ARMS}
    times, phases = [], []
    substeps = int(round(ds_period / PLANT_STEP))
    for tick in range(int(round(DURATION / ds_period)) + 1):
        t = tick * ds_period
        arms = {arm: ArmMeasurement(position[arm], rotation[arm], np.zeros(6), rotation[arm])
                for arm in ARMS}
        output = generator.step(arms, obj, ds_period,
                                start_episode=tick == int(round(START / ds_period)))
        phases.append((t, output.phase.phase.value))
        if outputs is not None:
            outputs.append(output)
        for step in range(substeps):
            for arm in ARMS:
                command = output.commands[arm]
                position[arm] = position[arm] + PLANT_STEP * command.v_world
                rotation[arm] = rotation_exp(PLANT_STEP * command.w_world) @ rotation[arm]
                paths[arm].append(position[arm].copy())
            times.append(t + (step + 1) * PLANT_STEP)
    return {arm: np.array(path) for arm, path in paths.items()}, np.array(times), phases


def test_reach_path_and_timing_agree_at_200_and_500_hz():
    slow_paths, slow_times, slow_phases = reach(0.005)
    fast_paths, fast_times, fast_phases = reach(0.002)
    assert (dict(slow_phases)[START], dict(fast_phases)[START]) == ('reach', 'reach')
    common = np.intersect1d(np.round(slow_times, 6), np.round(fast_times, 6))
    slow_index = np.searchsorted(np.round(slow_times, 6), common)
    fast_index = np.searchsorted(np.round(fast_times, 6), common)
    for arm in ARMS:
        travelled = np.linalg.norm(fast_paths[arm][-1] - fast_paths[arm][0])
        assert travelled > 0.4, 'the comparison must cover the reach'
        path_gap = max(np.min(np.linalg.norm(slow_paths[arm] - point, axis=1))
                       for point in fast_paths[arm][::20])
        assert path_gap <= 0.001, f'{arm}: paths {path_gap * 1e3:.2f} mm apart'
        # Holding a 0.5 m/s command for 5 ms instead of 2 ms delays the tool by ~1.5 ms along
        # its path, up to ~2 mm at equal times where the path bends; bound with margin.
        time_gap = np.max(np.linalg.norm(slow_paths[arm][slow_index]
                                         - fast_paths[arm][fast_index], axis=1))
        assert time_gap <= 0.0025, f'{arm}: {time_gap * 1e3:.2f} mm apart at equal times'


def test_the_object_ds_asks_for_motion_only_once_the_reach_has_begun():
    """Standby: zero desired object velocity; reach: the toss field the impact directions use."""
    outputs = []
    reach(0.005, outputs)
    standby = [o.object_velocity for o in outputs if o.phase.phase.value == 'standby']
    reaching = [o.object_velocity for o in outputs if o.phase.phase.value == 'reach']
    assert len(standby) >= 50 and len(reaching) >= 50
    assert np.all(np.array(standby) == 0.0)
    speeds = np.linalg.norm(reaching, axis=1)
    assert np.all(speeds > 0.1), f'reach object speeds down to {speeds.min():.3f} m/s'


def test_tick_schedule_keeps_its_rate_on_the_fri_grid_and_restarts_after_a_reset():
    """5 ms ticks on a 2 ms grid fall at 0, 6, 10, 16, 20 ms; an earlier stamp restarts them."""
    schedule = TickSchedule(0.005)
    ticks = []
    for cycle in range(11):
        t_ns = cycle * 2_000_000
        if schedule.due(t_ns):
            ticks.append((t_ns, schedule.take(t_ns)))
    assert ticks == [(0, 0.005), (6_000_000, 0.006), (10_000_000, 0.004),
                     (16_000_000, 0.006), (20_000_000, 0.004)]
    assert not schedule.went_back(20_000_000) and not schedule.due(20_000_000)
    assert schedule.went_back(2_000_000) and schedule.due(2_000_000)
    assert schedule.take(2_000_000) == 0.005
    assert not schedule.went_back(2_000_000)
