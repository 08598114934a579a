"""
The outgoing belt of the twin and the open container it carries (scenario `conveyor:` block).

The belt is a static slab on the front table; the box lands on it like on any surface. The
container is a body on a slide joint along world y, with a floor and four walls that touch the
box through explicit contact pairs (the same contact model as the pallet). It is driven
kinematically: before every physics step ContainerDrive writes the slide joint's position and
velocity from the belt's speed profile, so the container follows the belt exactly whatever the
box does to it, and MuJoCo sees its true velocity in every contact (friction drags a box resting
in it along). A mocap body was not used because MuJoCo treats a mocap body as fixed in its
contacts: a box on its floor would slide instead of being carried.

The belt speed (BeltSpeed) is the commanded speed (scenario, or live from BeltSpeed.command) times
1 + disturbance_amplitude sin(2 pi t / disturbance_period + phase), with the phase drawn from
the twin's seed; zero before container_start_time. The container moves toward world -y.
"""

from dataclasses import dataclass
import math

import mujoco
import numpy as np
from sim_bridge.scene import CONTACT_SOLIMP, CONTACT_SOLREF, OBJECT_BODY, scene_contact

CONTAINER_BODY = 'container'
# [kg]: the drive sets the container's motion; a mass only keeps the model regular.
CONTAINER_MASS = 2.0
CONTAINER_FRICTION = 0.6         # box against the container [-], as against the pallet
BELT_THICKNESS = 0.02            # [m]


@dataclass(frozen=True)
class ContainerSample:
    """A motion-capture sample of the container: stamp (sampling sim time) [s], centre [m]."""

    stamp: float
    p_world: np.ndarray


def container_geoms(config):
    """Return [(name, centre (3,), half sizes (3,))] of the floor and walls in the body frame."""
    inner_x, inner_y = config.inner_size
    t, h = config.wall_thickness, config.wall_height
    outer_x, outer_y = 0.5 * inner_x + t, 0.5 * inner_y + t
    wall_z = t + 0.5 * h
    return [('floor', (0.0, 0.0, 0.5 * t), (outer_x, outer_y, 0.5 * t)),
            ('wall_far', (0.5 * inner_x + 0.5 * t, 0.0, wall_z), (0.5 * t, outer_y, 0.5 * h)),
            ('wall_near', (-0.5 * inner_x - 0.5 * t, 0.0, wall_z), (0.5 * t, outer_y, 0.5 * h)),
            ('wall_left', (0.0, 0.5 * inner_y + 0.5 * t, wall_z), (0.5 * inner_x, 0.5 * t,
                                                                   0.5 * h)),
            ('wall_right', (0.0, -0.5 * inner_y - 0.5 * t, wall_z), (0.5 * inner_x, 0.5 * t,
                                                                     0.5 * h))]


def add_conveyor(spec, config):
    """Add the belt slab and the container (slide joint along y, paired with the box)."""
    belt = spec.worldbody.add_geom(
        name='belt', type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[config.belt_x, 0.0, config.belt_top_height - 0.5 * BELT_THICKNESS],
        size=[0.5 * config.belt_width, config.belt_half_length, 0.5 * BELT_THICKNESS])
    scene_contact(belt)
    belt.rgba = [0.15, 0.15, 0.15, 1.0]
    body = spec.worldbody.add_body(name=CONTAINER_BODY,
                                   pos=[config.belt_x, 0.0, config.belt_top_height])
    body.add_joint(name=CONTAINER_BODY, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0.0, 1.0, 0.0])
    body.explicitinertial = True
    body.mass = CONTAINER_MASS
    body.ipos = [0.0, 0.0, 0.0]
    body.inertia = [0.05, 0.05, 0.05]
    for name, centre, half_size in container_geoms(config):
        geom = body.add_geom(name=f'{CONTAINER_BODY}/{name}', type=mujoco.mjtGeom.mjGEOM_BOX,
                             pos=centre, size=half_size)
        geom.contype, geom.conaffinity = 0, 0
        geom.mass = 0.0
        geom.rgba = [0.2, 0.5, 0.8, 1.0]
        pair = spec.add_pair(name=f'{CONTAINER_BODY}/{name}_object',
                             geomname1=f'{CONTAINER_BODY}/{name}', geomname2=OBJECT_BODY)
        pair.condim = 3
        pair.friction = [CONTAINER_FRICTION, CONTAINER_FRICTION, 0.005, 0.0001, 0.0001]
        pair.solref = CONTACT_SOLREF
        pair.solimp = CONTACT_SOLIMP


def disturbed_speed(commanded, t, start_time, amplitude, period, phase):
    """Belt speed [m/s] at sim time t: the commanded speed times the sinusoidal disturbance."""
    if t < start_time:
        return 0.0
    return commanded * (1.0 + amplitude * math.sin(2.0 * math.pi * t / period + phase))


class BeltSpeed:
    """
    A belt's speed [m/s] toward world -y: the commanded speed times a sinusoidal disturbance.

    The command is the scenario's speed until a live one arrives (set); the disturbance's phase
    is drawn by the drive that owns the belt (reset); the belt stands still before start_time.
    """

    def __init__(self, config, start_time):
        self._config = config
        self._start_time = start_time
        self.phase = 0.0
        self.commanded = float(config.speed)

    def reset(self, phase):
        """Back to the scenario's commanded speed, with the disturbance phase [rad]."""
        self.phase = phase
        self.commanded = float(self._config.speed)

    def command(self, speed):
        """Command the belt speed [m/s] from now on."""
        self.commanded = float(speed)

    def at(self, t):
        """Return the belt speed [m/s] at sim time t, disturbance included."""
        config = self._config
        return disturbed_speed(self.commanded, t, self._start_time, config.disturbance_amplitude,
                               config.disturbance_period, self.phase)


class ContainerDrive:
    """
    Moves the container along the belt and samples it by motion capture.

    Its noise comes from the third child of SeedSequence(seed) (the twin's mocap and F/T noise
    use the first two), so adding a conveyor changes no other draw of a scenario.
    """

    def __init__(self, model, config, seed, mocap):
        self.config = config
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, CONTAINER_BODY)
        self._qpos = int(model.jnt_qposadr[joint])
        self._dof = int(model.jnt_dofadr[joint])
        self._seed_sequence = np.random.SeedSequence(seed).spawn(3)[2]
        self._mocap = mocap
        self.belt = BeltSpeed(config, config.container_start_time)

    def reset(self, data):
        """Container at its start in data, belt at the scenario's speed, noise reseeded."""
        self._rng = np.random.default_rng(self._seed_sequence)
        self.belt.reset(float(self._rng.uniform(0.0, 2.0 * math.pi)))
        self.position = float(self.config.container_start)
        self.velocity = 0.0
        data.qpos[self._qpos] = self.position
        data.qvel[self._dof] = self.velocity

    def drive(self, data, t, dt):
        """Write the container's state at t into data; advance it by dt for the next step."""
        self.velocity = -self.belt.at(t)
        data.qpos[self._qpos] = self.position
        data.qvel[self._dof] = self.velocity
        self.position += self.velocity * dt

    def pose(self, data):
        """Return (centre (3,) [m], velocity (3,) [m/s]): the floor's centre, ground truth."""
        return (np.array([self.config.belt_x, data.qpos[self._qpos],
                          self.config.floor_top_height]),
                np.array([0.0, data.qvel[self._dof], 0.0]))

    def sample(self, data, t):
        """Return the ContainerSample taken at t (the scenario's mocap position noise)."""
        centre, _ = self.pose(data)
        noise = self._rng.normal(0.0, self._mocap.position_noise, 3)
        return ContainerSample(stamp=t, p_world=centre + noise)

    def state(self):
        """Return the drive's state for ContainerDrive.set_state."""
        return (self.position, self.velocity, self.belt.commanded,
                self._rng.bit_generator.state)

    def set_state(self, state):
        """Restore a state taken by state()."""
        self.position, self.velocity, self.belt.commanded, rng_state = state
        self._rng.bit_generator.state = rng_state
