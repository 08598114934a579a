"""Exception hierarchy of the ROS-free core."""


class DualArmControlError(Exception):
    """Root of every error raised by dual_arm_control."""


class ConfigError(DualArmControlError, ValueError):
    """A configuration value or file is invalid; the message names the key, value and range."""


class InputError(DualArmControlError, ValueError):
    """A runtime input (state, measurement, command) is malformed or not finite."""


class SolverError(DualArmControlError, RuntimeError):
    """A numerical solver failed; carries the problem data and the solver status."""

    def __init__(self, message, status=None, problem=None):
        super().__init__(message)
        self.status = status
        self.problem = problem
