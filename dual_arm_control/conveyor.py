"""
The outgoing belt of a scenario: where it runs, how fast, and the open container it carries.

The belt lies on the front table along world y at x = belt_x; the container rides on it toward
world -y (from the left arm's side to the right arm's). Its commanded speed is the scenario's
`speed` (and, live, the newest value on the belt's speed topic); the twin adds the disturbance.
The container is an open box: a floor and four walls around an inner opening of
inner_size (along world x, along the belt). It is the scenario's `conveyor:` block.
"""

from dataclasses import dataclass

from dual_arm_control.core.settings import check_settings, setting


@dataclass(frozen=True)
class ConveyorConfig:
    """The outgoing belt and its container (world frame, SI units)."""

    belt_x: float = setting(
        0.92, 'World x of the belt centre line (the belt runs along world y).',
        unit='m', low=0.0, high=3.0)
    belt_width: float = setting(
        0.30, 'Width of the belt across its running direction.',
        unit='m', low=0.0, high=2.0, low_open=True)
    belt_half_length: float = setting(
        0.60, 'Half the belt length along world y, centred on y = 0.',
        unit='m', low=0.0, high=3.0, low_open=True)
    belt_top_height: float = setting(
        0.17, 'World z of the belt surface (the container floor rests on it).',
        unit='m', low=0.0, high=2.0)
    speed: float = setting(
        0.25, 'Commanded belt speed toward world -y.', unit='m/s', low=-2.0, high=2.0)
    disturbance_amplitude: float = setting(
        0.0, 'Relative amplitude of the sinusoidal belt speed disturbance (0.2: +-20 %).',
        low=0.0, high=1.0)
    disturbance_period: float = setting(
        2.0, 'Period of the belt speed disturbance (its phase is drawn from the seed).',
        unit='s', low=0.0, high=600.0, low_open=True)
    container_start: float = setting(
        0.55, 'World y of the container centre when the scenario starts.',
        unit='m', low=-3.0, high=3.0)
    container_start_time: float = setting(
        0.0, 'Sim time at which the belt starts carrying the container.',
        unit='s', low=0.0, high=600.0)
    inner_size: tuple = setting(
        (0.30, 0.20), 'Opening of the container: inner length across the belt (world x) and '
        'along it (world y).', unit='m', low=0.0, high=2.0, low_open=True, size=2)
    wall_height: float = setting(
        0.06, 'Height of the walls above the container floor.',
        unit='m', low=0.0, high=1.0, low_open=True)
    wall_thickness: float = setting(
        0.01, 'Thickness of the walls and of the floor.', unit='m', low=0.0, high=0.2,
        low_open=True)

    def __post_init__(self):
        check_settings(self)

    @property
    def floor_top_height(self):
        """World z [m] of the container's inner floor."""
        return self.belt_top_height + self.wall_thickness

    @property
    def rim_height(self):
        """World z [m] of the top of the container's walls (the plane of its opening)."""
        return self.floor_top_height + self.wall_height
