"""
The incoming belt of the twin: a moving surface that carries the box (scenario `incoming_belt:`).

The belt is a slab on a slide joint along world y that touches the box through an explicit
contact pair (the same contact model as the pallet; the arms do not touch it). It is driven
like the outgoing belt's container (sim_bridge.belt): before every physics step
IncomingBeltDrive writes the slide joint's velocity from the belt's speed profile and puts its
position back to zero, so the slab stays where it is while MuJoCo sees its surface moving in
every contact: friction carries a box resting on it, as a real belt's surface does, and a box
held still slides on it.

The belt speed (belt.BeltSpeed) is the commanded speed (scenario, or live) times
1 + disturbance_amplitude sin(2 pi t / disturbance_period + phase), with the phase drawn from
the twin's seed; zero before start_time. Positive speeds carry the box toward world -y.
"""

import math

import mujoco
import numpy as np
from sim_bridge.belt import add_conveyor, BELT_THICKNESS, BeltSpeed
from sim_bridge.scene import (build_spec, CONTACT_SOLIMP, CONTACT_SOLREF, OBJECT_BODY,
                              scene_index)

INCOMING_BELT_BODY = 'incoming_belt'
# [kg]: the drive sets the belt's motion; a mass only keeps the model regular (heavy, so the
# box's friction barely changes its velocity within a physics step).
INCOMING_BELT_MASS = 20.0
INCOMING_BELT_FRICTION = 0.6     # box against the belt [-], as against the pallet


def build_cell_model(cell, scenario):
    """Compile the cell of a scenario with its belts, if it has any: (MjModel, SceneIndex)."""
    spec = build_spec(cell, scenario.object)
    if scenario.conveyor is not None:
        add_conveyor(spec, scenario.conveyor)
    if scenario.incoming_belt is not None:
        add_incoming_belt(spec, scenario.incoming_belt)
    model = spec.compile()
    return model, scene_index(model)


def add_incoming_belt(spec, config):
    """Add the incoming belt: a slab on a slide joint along y, paired with the box."""
    body = spec.worldbody.add_body(
        name=INCOMING_BELT_BODY,
        pos=[config.belt_x, 0.0, config.belt_top_height - 0.5 * BELT_THICKNESS])
    body.add_joint(name=INCOMING_BELT_BODY, type=mujoco.mjtJoint.mjJNT_SLIDE,
                   axis=[0.0, 1.0, 0.0])
    body.explicitinertial = True
    body.mass = INCOMING_BELT_MASS
    body.ipos = [0.0, 0.0, 0.0]
    body.inertia = [1.0, 1.0, 1.0]
    geom = body.add_geom(name=INCOMING_BELT_BODY, type=mujoco.mjtGeom.mjGEOM_BOX,
                         size=[0.5 * config.belt_width, config.belt_half_length,
                               0.5 * BELT_THICKNESS])
    geom.contype, geom.conaffinity = 0, 0
    geom.mass = 0.0
    geom.rgba = [0.1, 0.1, 0.1, 1.0]
    pair = spec.add_pair(name=f'{INCOMING_BELT_BODY}_object', geomname1=INCOMING_BELT_BODY,
                         geomname2=OBJECT_BODY)
    pair.condim = 3
    pair.friction = [INCOMING_BELT_FRICTION, INCOMING_BELT_FRICTION, 0.005, 0.0001, 0.0001]
    pair.solref = CONTACT_SOLREF
    pair.solimp = CONTACT_SOLIMP


class IncomingBeltDrive:
    """
    Drives the incoming belt's surface.

    Its disturbance phase comes from the fourth child of SeedSequence(seed) (the twin's mocap
    and F/T noise use the first two, the container the third), so adding the belt changes no
    other draw of a scenario.
    """

    def __init__(self, model, config, seed):
        self.config = config
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, INCOMING_BELT_BODY)
        self._qpos = int(model.jnt_qposadr[joint])
        self._dof = int(model.jnt_dofadr[joint])
        self._seed_sequence = np.random.SeedSequence(seed).spawn(4)[3]
        self.belt = BeltSpeed(config, config.start_time)

    def reset(self, data):
        """Belt at rest in data, at the scenario's commanded speed, phase redrawn."""
        rng = np.random.default_rng(self._seed_sequence)
        self.belt.reset(float(rng.uniform(0.0, 2.0 * math.pi)))
        self.velocity = 0.0
        data.qpos[self._qpos] = 0.0
        data.qvel[self._dof] = 0.0

    def drive(self, data, t):
        """Write the belt surface's state at t into data: in place, moving at the belt speed."""
        self.velocity = -self.belt.at(t)
        data.qpos[self._qpos] = 0.0
        data.qvel[self._dof] = self.velocity

    def surface_velocity(self):
        """Return the belt surface's velocity (3,) [m/s] in world, ground truth."""
        return np.array([0.0, self.velocity, 0.0])

    def state(self):
        """Return the drive's state for IncomingBeltDrive.set_state."""
        return (self.velocity, self.belt.commanded)

    def set_state(self, state):
        """Restore a state taken by state()."""
        self.velocity, self.belt.commanded = state
