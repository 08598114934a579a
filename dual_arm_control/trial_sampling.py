"""
Trials of a randomized scenario: trial number i as a concrete Scenario, drawn reproducibly.

The ranges come from the scenario's randomization block (dual_arm_control.randomization).
"""

from dataclasses import replace
import math

from dual_arm_control.catalogue import load_catalogue
from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.description.cell import load_cell
from dual_arm_control.randomization import Randomization
from dual_arm_control.scenario import ObjectConfig
import numpy as np

# The uniform draws of one trial, in the order they are taken from its first generator.
TRIAL_DRAWS = ('object_x', 'object_y', 'object_yaw', 'mass', 'size_scale', 'friction',
               'mocap_noise')
# Draws added later come from a second generator, so the first one's draws (and the trial's
# noise seed) stay those of the files written before them.
LATER_DRAWS = ('object_type', 'mocap_latency', 'release_yaw')
# The conveyor's draws, from a third generator.
CONVEYOR_DRAWS = ('belt_speed', 'container_start', 'container_start_time')
# The landing target's offsets, from a fourth generator.
TARGET_DRAWS = ('landing_target_x', 'landing_target_y')


def sample_trial(scenario, trial_index, cell=None, catalogue_path=None):
    """
    Return trial number trial_index of scenario: a concrete Scenario, its randomization drawn.

    Deterministic in (scenario.seed, trial_index): a generator seeded with
    SeedSequence([seed, trial_index]) draws one uniform number per quantity of TRIAL_DRAWS in a
    fixed order (adding a range to a file leaves the other quantities' draws unchanged), then
    the trial's own seed, so every trial has different but reproducible sensor noise; a
    second, SeedSequence([seed, trial_index, 1]), draws LATER_DRAWS, and a third,
    SeedSequence([seed, trial_index, 2]), the CONVEYOR_DRAWS of a scenario's conveyor, and a
    fourth, SeedSequence([seed, trial_index, 3]), the TARGET_DRAWS (the landing target's
    offsets along world x and y). A
    drawn object type replaces the box's size, mass and friction by its catalogue values
    before the ranges apply.
    The box rests on the surface below its drawn position as the scenario's did; resting
    targets (landing_target, place) follow its height; a drawn release_yaw sets the yaw of the
    release orientation. The trial has no randomization and no
    path.
    """
    if isinstance(trial_index, bool) or not isinstance(trial_index, int) or trial_index < 0:
        raise ConfigError(f'trial_index must be an integer >= 0, got {trial_index!r}')
    cell = cell or load_cell()
    generator = np.random.default_rng(np.random.SeedSequence([scenario.seed, trial_index]))
    draw = dict(zip(TRIAL_DRAWS, generator.random(len(TRIAL_DRAWS))))
    trial_seed = int(generator.integers(0, 2 ** 31))
    later = np.random.default_rng(np.random.SeedSequence([scenario.seed, trial_index, 1]))
    draw.update(zip(LATER_DRAWS, later.random(len(LATER_DRAWS))))
    conveyor_draws = np.random.default_rng(np.random.SeedSequence([scenario.seed, trial_index,
                                                                   2]))
    draw.update(zip(CONVEYOR_DRAWS, conveyor_draws.random(len(CONVEYOR_DRAWS))))
    target_draws = np.random.default_rng(np.random.SeedSequence([scenario.seed, trial_index,
                                                                 3]))
    draw.update(zip(TARGET_DRAWS, target_draws.random(len(TARGET_DRAWS))))
    spec = scenario.randomization or Randomization()

    def from_range(name, default):
        interval = getattr(spec, name)
        if interval is None:
            return default
        return float(interval[0] + (interval[1] - interval[0]) * draw[name])

    def offset(name, half_range):
        return float(half_range * (2.0 * draw[name] - 1.0))

    box = scenario.object
    kind, size, mass, friction = box.type, np.array(box.size), box.mass, box.friction
    if spec.object_types is not None:
        types = spec.object_types
        kind = types[min(int(draw['object_type'] * len(types)), len(types) - 1)]
        catalogue_entry = load_catalogue(catalogue_path)[kind]
        size = np.array(catalogue_entry.size, dtype=float)
        mass, friction = catalogue_entry.mass, catalogue_entry.friction
    size = size * from_range('size_scale', 1.0)
    lift = 0.5 * (size[2] - box.size[2])
    x, y, z = box.position
    new_x = x + offset('object_x', spec.object_position[0])
    new_y = y + offset('object_y', spec.object_position[1])
    new_z = z + (cell.surface_height(new_x, new_y) - cell.surface_height(x, y)) + lift
    yaw = math.remainder(box.yaw + offset('object_yaw', spec.object_yaw), 2.0 * math.pi)
    trial_object = ObjectConfig(kind, size, from_range('mass', mass),
                                from_range('friction', friction), [new_x, new_y, new_z], yaw)
    mocap = scenario.sensors.mocap
    mocap = replace(mocap, position_noise=from_range('mocap_noise', mocap.position_noise),
                    latency=from_range('mocap_latency', mocap.latency))

    release_orientation = scenario.release_orientation
    if spec.release_yaw is not None:
        roll, pitch, _ = (0.0, 0.0, 0.0) if release_orientation is None else release_orientation
        release_orientation = (roll, pitch, from_range('release_yaw', 0.0))

    def raised(position):
        if position is None:
            return None
        moved = np.array(position, dtype=float) + [0.0, 0.0, lift]
        moved.setflags(write=False)
        return moved

    conveyor = scenario.conveyor
    if conveyor is not None:
        conveyor = replace(
            conveyor, speed=from_range('belt_speed', conveyor.speed),
            container_start=from_range('container_start', conveyor.container_start),
            container_start_time=from_range('container_start_time',
                                            conveyor.container_start_time))
    landing_target = scenario.landing_target
    if spec.landing_target is not None and landing_target is not None:
        landing_target = np.array(landing_target, dtype=float) + [
            offset('landing_target_x', spec.landing_target[0]),
            offset('landing_target_y', spec.landing_target[1]), 0.0]
    return replace(scenario, seed=trial_seed, object=trial_object, conveyor=conveyor,
                   landing_target=raised(landing_target), place=raised(scenario.place),
                   release_orientation=release_orientation,
                   sensors=replace(scenario.sensors, mocap=mocap), randomization=None,
                   path=None)
