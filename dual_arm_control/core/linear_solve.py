"""
np.linalg.solve for the small dense systems of the per-cycle loops, without its dispatch.

np.linalg.solve checks and converts its arguments in Python, then runs LAPACK's gesv through
NumPy's linalg gufuncs, inside an errstate that turns a singular matrix into LinAlgError. For
the 6 x 6 systems of the torque loop that wrapper costs twice the solve. solve() calls the
same gufunc directly (the same numbers); a result that is not finite is computed again by
np.linalg.solve, so a singular system still raises LinAlgError (after NumPy's invalid-value
warning of the first attempt). The systems solved per cycle are regularised, symmetric positive
definite ones.
"""

from dual_arm_control.core.validation import all_finite
import numpy as np

try:
    from numpy.linalg import _umath_linalg
    _SOLVE_VECTOR, _SOLVE_MATRIX = _umath_linalg.solve1, _umath_linalg.solve
except (ImportError, AttributeError):
    _SOLVE_VECTOR = _SOLVE_MATRIX = None


def solve(matrix, right_hand_side):
    """Return x with matrix @ x = right_hand_side: float64 (n, n) and (n,) or (n, k) arrays."""
    if _SOLVE_VECTOR is not None:
        gufunc = _SOLVE_VECTOR if right_hand_side.ndim == 1 else _SOLVE_MATRIX
        solution = gufunc(matrix, right_hand_side, signature='dd->d')
        if all_finite(solution):
            return solution
    return np.linalg.solve(matrix, right_hand_side)
