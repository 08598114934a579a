"""
The incoming belt of a scenario: a belt that carries the box across the front of the robots.

The belt runs along world y at x = belt_x, through the pallet's position, with its surface at
belt_top_height (above the pallet's top, so the box rests on the belt only). It carries the box
toward world -y (from the left arm's side to the right arm's) at its commanded `speed` (and,
live, the newest value on its speed topic); the twin adds the disturbance and starts the belt
at start_time. It is the scenario's `incoming_belt:` block.
"""

from dataclasses import dataclass

from dual_arm_control.core.settings import check_settings, setting


@dataclass(frozen=True)
class IncomingBeltConfig:
    """The incoming belt (world frame, SI units)."""

    belt_x: float = setting(
        0.41, 'World x of the incoming belt centre line (the belt runs along world y).',
        unit='m', low=0.0, high=3.0)
    belt_width: float = setting(
        0.30, 'Width of the incoming belt across its running direction.',
        unit='m', low=0.0, high=2.0, low_open=True)
    belt_half_length: float = setting(
        0.80, 'Half the incoming belt length along world y, centred on y = 0.',
        unit='m', low=0.0, high=3.0, low_open=True)
    belt_top_height: float = setting(
        0.23, 'World z of the incoming belt surface (the box rests on it).',
        unit='m', low=0.0, high=2.0)
    speed: float = setting(
        0.2, 'Commanded incoming belt speed toward world -y.', unit='m/s', low=-2.0, high=2.0)
    disturbance_amplitude: float = setting(
        0.0, 'Relative amplitude of the sinusoidal belt speed disturbance (0.2: +-20 %).',
        low=0.0, high=1.0)
    disturbance_period: float = setting(
        2.0, 'Period of the belt speed disturbance (its phase is drawn from the seed).',
        unit='s', low=0.0, high=600.0, low_open=True)
    start_time: float = setting(
        0.0, 'Sim time at which the incoming belt starts moving.',
        unit='s', low=0.0, high=600.0)

    def __post_init__(self):
        check_settings(self)
