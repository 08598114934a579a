"""
Arm collisions in the twin: MuJoCo contacts of an arm with anything but the box through a pad.

Every arm link collides with the pallet, the tables, the floor, the box and the other arm's
links (sim_bridge.scene's collision bits); the pads touch the box through their explicit pairs.
A collision is counted when a geom pair starts touching, checked once per FRI cycle (the end of
its physics steps), so a link resting on the pallet for a second counts once.
"""

from dataclasses import dataclass

from dual_arm_control.core.arms import ARMS
import numpy as np


@dataclass(frozen=True)
class ArmCollision:
    """The start of a contact: sim time [s] and the two geoms' names."""

    time: float
    geoms: tuple


class ArmCollisionMonitor:
    """Finds the arm collisions that begin at each physics step of one compiled cell model."""

    def __init__(self, model, index):
        """Classify the geoms of model (SceneIndex index): arm geoms, pad-box pairs."""
        self._model = model
        prefixes = tuple(f'{arm}/' for arm in ARMS)
        self._arm_geoms = np.array([
            model.body(int(model.geom_bodyid[geom])).name.startswith(prefixes)
            for geom in range(model.ngeom)], dtype=bool)
        self._pad_object_pairs = frozenset(
            tuple(sorted((int(index.arms[arm].pad_geom), int(index.object_geom))))
            for arm in ARMS)
        self.colliding_pairs = frozenset()

    def reset(self):
        """Forget the pairs in contact (a new episode)."""
        self.colliding_pairs = frozenset()

    def update(self, data, time):
        """Return the ArmCollisions that touch in data now and did not at the previous call."""
        pairs = frozenset()
        if data.ncon:
            geoms = data.contact.geom
            involved = self._arm_geoms[geoms].any(axis=1)
            if involved.any():
                pairs = frozenset((int(a), int(b)) if a < b else (int(b), int(a))
                                  for a, b in geoms[involved]) - self._pad_object_pairs
        if not pairs and not self.colliding_pairs:
            return []
        started = pairs - self.colliding_pairs
        self.colliding_pairs = pairs
        return [ArmCollision(time, (self._model.geom(a).name, self._model.geom(b).name))
                for a, b in sorted(started)]
