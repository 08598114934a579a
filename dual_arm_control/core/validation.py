"""Checks shared by the typed config objects and the core entry points."""

import math

from dual_arm_control.core.exceptions import ConfigError, InputError
import numpy as np

# Largest array whose finiteness is summed in Python floats rather than by a dot product [-].
SMALL_ARRAY_SIZE = 64


def check_range(name, value, low=-math.inf, high=math.inf, unit='', low_open=False,
                high_open=False):
    """
    Raise ConfigError unless low <= value <= high (or strict where *_open); return value.

    The message names the field, the value, the allowed interval and the unit, so a refused
    parameter explains itself.
    """
    unit_text = f' {unit}' if unit else ''
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f'{name} must be a number{unit_text}, got {value!r}') from None
    if not math.isfinite(number):
        raise ConfigError(f'{name} must be finite, got {value!r}')
    too_low = number <= low if low_open else number < low
    too_high = number >= high if high_open else number > high
    if too_low or too_high:
        left = '(' if low_open else '['
        right = ')' if high_open else ']'
        raise ConfigError(
            f'{name} = {number:g}{unit_text} is outside {left}{low:g}, {high:g}{right}{unit_text}')
    return value


def check_vector(name, value, size, unit=''):
    """Return value as a finite float array of the given size, or raise ConfigError."""
    try:
        array = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f'{name} must be {size} numbers, got {value!r}') from None
    if array.size != size:
        raise ConfigError(f'{name} must have {size} elements, got {array.size}')
    if not np.all(np.isfinite(array)):
        raise ConfigError(f'{name} must be finite, got {array.tolist()}')
    return array


def frozen_vector(name, value, size, unit=''):
    """Return check_vector(...) as a read-only copy, for the fields of frozen configs."""
    array = check_vector(name, value, size, unit).copy()
    array.setflags(write=False)
    return array


def all_finite(array):
    """
    Return True if every entry of a float array is finite.

    A finite sum is the fast proof (NaN and Inf propagate): of Python floats for the small
    arrays of a tick (no NumPy dispatch), of squares by a dot product for large ones. Only an
    overflowing sum of finite values needs the element-wise check.
    """
    flat = array.ravel()
    if flat.size <= SMALL_ARRAY_SIZE:
        total = sum(flat.tolist())
    else:
        with np.errstate(over='ignore'):
            total = flat.dot(flat)
    return math.isfinite(total) or bool(np.isfinite(array).all())


def finite_array(name, value, shape=None):
    """Return value as a float array, raising InputError if it is not finite or misshaped."""
    array = np.asarray(value, dtype=float)
    if shape is not None and array.shape != shape and array.shape != tuple(shape):
        raise InputError(f'{name} must have shape {tuple(shape)}, got {array.shape}')
    if not all_finite(array):
        raise InputError(f'{name} contains NaN or Inf')
    return array


def finite_rows(names, values, size):
    """
    Return values as a read-only (len(names), size) float array, a row per name.

    One conversion and one finiteness check for all rows; a bad row raises finite_array's
    InputError, which names it.
    """
    try:
        rows = np.array(values, dtype=float)
    except (TypeError, ValueError):
        rows = None
    if rows is None or rows.shape != (len(names), size) or not all_finite(rows):
        for name, value in zip(names, values):
            finite_array(name, value, (size,))
        rows = np.array(values, dtype=float)
    rows.flags.writeable = False
    return rows
