"""
Time one tick of the coordinated reach-with-impact DS for both arms.

One tick = impact_ds_velocity (nominal field, activations, eq. 6 target field, modulation)
+ grasp_distance + reach_speed + boosted_coordinated_velocity, evaluated along a reach
trajectory of the paper geometry so that every activation regime is visited. Target: a median
at or below 150 us on the project machine. Run: python -m dual_arm_control.benchmarks.ds_bench
"""

import time

from dual_arm_control.core.cooperative import CoordinationConfig
from dual_arm_control.core.impact import (
    grasp_distance, impact_direction, impact_ds_velocity, impact_geometry, ImpactConfig,
    max_impact_tilt)
from dual_arm_control.core.speed_shaping import (
    boosted_coordinated_velocity, reach_speed, SpeedProfileConfig)
import numpy as np

OBJECT_POSITION = np.array([0.41, 0.0, 0.32])
GRASP_POINTS = np.array([OBJECT_POSITION + [0.0, 0.1, 0.0], OBJECT_POSITION - [0.0, 0.1, 0.0]])
CONTACT_NORMALS = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
OBJECT_VELOCITY = np.array([0.7603, 0.0, 0.3801])
START = np.array([0.35, 0.31, 0.80, 0.35, -0.31, 0.80])


def ds_tick(x, geometry, impact, speed_profile):
    """Return the boosted coordinated velocity (6,) [m/s] at x (6,) [m]: one DS tick."""
    output = impact_ds_velocity(x, geometry)
    speed = reach_speed(grasp_distance(x, geometry), impact.impact_speed, speed_profile)
    return boosted_coordinated_velocity(output.velocity, speed)


def bench_ds_tick(ticks=2000, dt=0.005):
    """
    Return (median, p99) [us] of ds_tick over a reach of `ticks` steps of dt [s].

    The state is integrated with the DS output, so the ticks span far reach, transitory
    attractor and impact run (the run restarts from START when both pads pass contact).
    """
    coordination, impact = CoordinationConfig(), ImpactConfig()
    speed_profile = SpeedProfileConfig()
    tilt = max_impact_tilt(impact)
    directions = np.array([impact_direction(normal, OBJECT_VELOCITY, tilt)
                           for normal in CONTACT_NORMALS])
    geometry = impact_geometry(GRASP_POINTS, directions, coordination, impact)
    x = START.copy()
    durations = np.empty(ticks)
    for index in range(ticks):
        begin = time.perf_counter()
        velocity = ds_tick(x, geometry, impact, speed_profile)
        durations[index] = time.perf_counter() - begin
        x = x + dt * velocity
        if np.all(np.einsum('ij,ij->i', CONTACT_NORMALS, x.reshape(2, 3) - GRASP_POINTS) > 0.0):
            x = START.copy()
    micros = durations * 1e6
    return float(np.median(micros)), float(np.percentile(micros, 99))


def bench_motion_generator_step(ticks=2000, dt=0.005):
    """
    Return (median, p99) microseconds of a whole DualArmMotionGenerator.step while reaching.

    That is the node's tick: FT compensation, contact, phases, grasp frames, the impact DS,
    speed shaping and the orientation DS of both arms.
    """
    from dual_arm_control.core.motion_generator import DualArmMotionGenerator
    from dual_arm_control.core.motion_signals import ArmMeasurement, ObjectMeasurement
    from dual_arm_control.description.cell import load_cell
    from dual_arm_control.runtime.configuration import motion_config_for_scenario
    from dual_arm_control.scenario import load_scenario, scenario_path
    cell = load_cell()
    scenario = load_scenario(scenario_path('paper_toss'), cell=cell)
    generator = DualArmMotionGenerator(motion_config_for_scenario(scenario, cell))
    arms = {arm: ArmMeasurement(np.array(cell.arm(arm).standby_position),
                                np.array(cell.arm(arm).R_world_standby), np.zeros(6),
                                np.array(cell.arm(arm).R_world_standby))
            for arm in ('left', 'right')}
    obj = ObjectMeasurement(np.array(scenario.object.position), np.eye(3), np.zeros(3))
    durations = []
    for tick in range(ticks + 100):
        started = time.perf_counter()
        generator.step(arms, obj, dt, start_episode=tick == 50)
        durations.append(time.perf_counter() - started)
    micros = np.array(durations[100:]) * 1e6
    return float(np.median(micros)), float(np.percentile(micros, 99))


def main():
    """Print median and p99 of one DS tick for both arms, field alone and whole node tick."""
    median, p99 = bench_ds_tick()
    print(f'DS tick (modulation + impact + speed shaping, both arms): '
          f'median {median:.1f} us, p99 {p99:.1f} us (target median <= 150 us)')
    median, p99 = bench_motion_generator_step()
    print(f'whole motion generator step (FT, contact, phases, DS, orientation, both arms): '
          f'median {median:.1f} us, p99 {p99:.1f} us')


if __name__ == '__main__':
    main()
