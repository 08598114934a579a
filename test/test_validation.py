"""The finiteness and shape checks every core entry point uses (core.validation)."""

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.validation import all_finite, finite_array, finite_rows
import numpy as np
import pytest


@pytest.mark.parametrize('size', [3, 9, 64, 65, 500])
def test_all_finite_finds_one_bad_entry_in_small_and_large_arrays(size):
    values = np.linspace(-1.0, 1.0, size)
    assert all_finite(values)
    for bad in (np.nan, np.inf, -np.inf):
        for index in (0, size // 2, size - 1):
            spoiled = values.copy()
            spoiled[index] = bad
            assert not all_finite(spoiled)
    both_infinities = values.copy()
    both_infinities[:2] = (np.inf, -np.inf)
    assert not all_finite(both_infinities)


@pytest.mark.parametrize('size', [3, 500])
def test_all_finite_accepts_finite_values_whose_sum_overflows(size):
    assert all_finite(np.full(size, 1e308))
    assert all_finite(np.full((3, 3), -1e308))


def test_finite_array_names_the_value_it_refuses():
    with pytest.raises(InputError, match='p_world_tool contains NaN'):
        finite_array('p_world_tool', [0.0, np.nan, 0.0], (3,))
    with pytest.raises(InputError, match=r'R_world_tool must have shape \(3, 3\)'):
        finite_array('R_world_tool', np.eye(4), (3, 3))


def test_finite_rows_are_read_only_rows_and_a_bad_row_is_named():
    names = ('p_world_tool', 'v_world_object', 'p_world_place')
    rows = finite_rows(names, [np.zeros(3), [0.1, 0.2, 0.3], (1.0, 0.0, 0.5)], 3)
    np.testing.assert_array_equal(rows[1], [0.1, 0.2, 0.3])
    with pytest.raises(ValueError):
        rows[0][0] = 1.0
    with pytest.raises(InputError, match='v_world_object contains NaN or Inf'):
        finite_rows(names, [np.zeros(3), [0.1, np.inf, 0.3], np.zeros(3)], 3)
    with pytest.raises(InputError, match=r'p_world_place must have shape \(3,\), got \(2,\)'):
        finite_rows(names, [np.zeros(3), np.zeros(3), np.zeros(2)], 3)
    with pytest.raises(InputError, match=r'v_world_object must have shape \(3,\), got \(1, 3\)'):
        finite_rows(names, [np.zeros(3), np.zeros((1, 3)), np.zeros(3)], 3)
