"""
Contact wrench distribution between the two grabber pads (paper section II-E, eq. 10).

Decision variables:

    x = [w_L, w_R | s | t]      (6 + 6 + 6 + 6 = 24)

w_i = [f_i; m_i]: wrench applied BY pad i ON the object, in the pad frame (z = contact normal
into the object), moment about the contact point [N, N m]; the world-frame pad wrenches are
f_e = blockdiag(R_i, R_i) w_i. s (6,): balance slack in the world frame, s = f_o^d - G f_e,
the part of the desired object wrench not produced; t (6,): epigraph of |s|.

    minimise   ||s||^2_{W_o} + rho^T t + ||w - w^*||^2_{W_e}
    subject to G f_e + s = f_o^d,  -t <= s <= t
               per pad in contact (C_f f_e <= d_f of eq. 10):
               f_min <= f_z <= f_max                          (normal force bounds)
               |f_x|, |f_y| <= mu / sqrt(2) f_z               (inscribed friction pyramid)
               |m_z| <= gamma_t f_z                           (torsional friction)
               |m_x| <= half_width f_z, |m_y| <= half_length f_z   (centre of pressure)
               per pad farther than the contact distance: w_i = 0       (Q_eo f_e = 0)

W_e is isotropic within forces and within moments, so ||w - w^*||_{W_e} equals eq. 10's
||f_e - f_e^*||_{W_e} with f_e^* = f_squeeze along each pad normal. Pad-frame variables make
the constraint rows, the Hessian and the gradient constant: per tick only the equality matrix
G blockdiag(R_i, R_i) and f_o^d change (the contact rows change when a pad makes or breaks
contact).

With rho = 0 this is eq. 10, the balance residual written as a variable (residual reported).
The L1 term rho^T |s| makes the penalty exact: whenever the contact constraints admit
G f_e = f_o^d and rho exceeds the balance multipliers (about 2 W_e |w - w^*|, tens), the
optimal slack is exactly zero, the net wrench is the desired one and the squeeze is the least
the constraints allow. A quadratic W_o alone either leaks (the reference's 100 / 200 against
W_e 0.5 / 5 let the squeeze preference shift the net wrench by up to ~1 N) or, made stiff
enough, gives multipliers of W_o |s| ~ 1e10 that proxsuite cannot converge on once the slack
is active. When the wrench is not achievable the slack carries the unachievable part and the
result says so (feasible = False). Normal-force bounds are QP constraints; nothing is clamped
after the solve. A released pad's rows become the identity with bounds [0, 0] (linearly
independent; collapsing f_z to [0, 0] in the contact rows would make the multipliers
degenerate).
"""

import dataclasses
import math

from dual_arm_control.core.exceptions import InputError, SolverError
from dual_arm_control.core.geometry import skew
from dual_arm_control.core.pad_contact import PAD_ORDER
from dual_arm_control.core.settings import check_settings, setting
from dual_arm_control.core.validation import check_range
import numpy as np
import proxsuite

# Largest normal force a pad may be asked for [N]: the range of every normal-force setting.
NORMAL_FORCE_LIMIT = 1000.0
_N_WRENCH = 12
_N_SLACK = 6
_N_VARIABLES = _N_WRENCH + 2 * _N_SLACK
_N_PAD_ROWS = 11
_N_INEQUALITIES = 2 * _N_PAD_ROWS + 2 * _N_SLACK
_RELEASED_PAD_ROWS = np.vstack((np.eye(6), np.zeros((_N_PAD_ROWS - 6, 6))))
_RELEASED_PAD_LOWER = np.concatenate((np.zeros(6), np.full(_N_PAD_ROWS - 6, -np.inf)))
_RELEASED_PAD_UPPER = np.concatenate((np.zeros(6), np.full(_N_PAD_ROWS - 6, np.inf)))
_SLACK = slice(_N_WRENCH, _N_WRENCH + _N_SLACK)
_SLACK_BOUND = slice(_N_WRENCH + _N_SLACK, _N_VARIABLES)
_NEVER = 2 ** 30
_INPUT_NAMES = ('object_wrench', 'p_world_object', 'left p_world_contact', 'left R_world_pad',
                'left normal_distance', 'right p_world_contact', 'right R_world_pad',
                'right normal_distance')
_INPUT_SHAPES = ((6,), (3,), (3,), (3, 3), (), (3,), (3, 3), ())
_SOLVED = proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
_WARM_START = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
_COLD_START = proxsuite.proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS


@dataclasses.dataclass(frozen=True)
class WrenchQPConfig:
    """
    Contact model, weights and solver settings of the wrench distribution QP (eq. 10).

    Defaults follow the reference setup (mu 0.9, contact distance 0.055 m, weights 0.5 / 5
    on pad forces / moments, 100 / 200 on the balance residual) and the paper's 0.15 x 0.10 m
    pad, plus the exact L1 balance weight rho (module text). The
    torsion arm is physical (metres; the reference's 0.9 is dimensionally a length too):
    uniform pressure on the pad gives mu * 0.0485 m = 0.044 m; 0.03 m leaves margin for the
    coupling with tangential friction, which separate pyramid and torsion rows ignore. The
    centre-of-pressure limits are the pad's half sizes (the reference used 0.05 m for both).
    The normal-force bounds (70-105 N) are above the reference's 30-45 N (min_normal_force).
    """

    friction_coefficient: float = setting(
        0.6, 'Coulomb friction mu between pad and object; pyramid half-width mu / sqrt(2). The '
        'grip is designed for the lowest friction the pads may meet, not a typical one: '
        "0.6, the low end of the catalogue scenarios' 0.6-1.0 (catalogue_random, seed 11, "
        '300 trials: 247 succeed and no grasp fails to hold, against 242 and 9 with mu 0.9).',
        low=0, high=5.0, low_open=True)
    torsion_arm: float = setting(
        0.02, "gamma_t: torsional friction limit |m_z| <= gamma_t f_z; below the pads' real "
        "torsional friction (mu times the pad's mean radius 0.048 m in the twin's contact "
        'model, sim_bridge/scene.py: 0.029 m at the lowest randomized mu 0.6).',
        unit='m', low=0, high=1.0)
    pad_half_length: float = setting(
        0.075, 'Half extent of the pad along the pad x axis: |m_y| <= this * f_z.',
        unit='m', low=0, high=1.0, low_open=True)
    pad_half_width: float = setting(
        0.05, 'Half extent of the pad along the pad y axis: |m_x| <= this * f_z.',
        unit='m', low=0, high=1.0, low_open=True)
    min_normal_force: float = setting(
        70.0, 'Lower bound of the normal force of a pad in contact. Sized to the carry, not '
        "only to the box's weight: as the box is accelerated its velocity along the squeeze "
        "axis wanders about 0.1 m/s from the desired one, and the controllers' damping on that "
        'error (400 N s/m) pulls a pad off its face with 40 N and more. At 30 N the pads of '
        'light boxes let go mid-carry (catalogue_random, seed 11, 300 trials: slip p95 5.8 mm, '
        '31 boxes above 5 mm; at 70 N 4.5 mm and 6). Heavy boxes get more '
        '(wrench_distribution.qp_config_for_mass), boxes grasped square less '
        '(wrench_distribution square_grip_force).', unit='N', low=0,
        high=NORMAL_FORCE_LIMIT)
    max_normal_force: float = setting(
        105.0, 'Upper bound of the normal force of a pad in contact, above min_normal_force.',
        unit='N', low=0, high=NORMAL_FORCE_LIMIT, low_open=True)
    squeeze_force: float = setting(
        70.0, 'Normal force of the preferred wrench f_e^* of a pad in contact, at most '
        'max_normal_force.', unit='N', low=0, high=NORMAL_FORCE_LIMIT)
    contact_distance: float = setting(
        0.055, 'A pad whose normal distance to its face exceeds this may not push (Q_eo).',
        unit='m', low=0, high=1.0)
    force_weight: float = setting(
        0.5, 'W_e diagonal on pad forces.', unit='1/N^2', low=0, high=1000.0, low_open=True)
    moment_weight: float = setting(
        5.0, 'W_e diagonal on pad moments.', unit='1/(N m)^2', low=0, high=1000.0, low_open=True)
    balance_force_weight: float = setting(
        100.0, 'W_o diagonal on the force part of the balance residual (reference 100).',
        unit='1/N^2', low=0, high=1e6, low_open=True)
    balance_moment_weight: float = setting(
        200.0, 'W_o diagonal on the moment part of the balance residual (reference 200).',
        unit='1/(N m)^2', low=0, high=1e6, low_open=True)
    balance_force_l1_weight: float = setting(
        1000.0, 'rho on |force residual|; exact while above the balance multipliers.',
        unit='1/N', low=0, high=1e6)
    balance_moment_l1_weight: float = setting(
        1000.0, 'rho on |moment residual|; exact while above the balance multipliers.',
        unit='1/(N m)', low=0, high=1e6)
    slack_tolerance: float = setting(
        1e-3, 'The solution counts as feasible while ||s|| <= this.',
        unit='N, N m', low=0, high=1000.0, low_open=True)
    solver_tolerance: float = setting(
        1e-9, 'proxsuite eps_abs on primal and dual residuals.',
        unit='N, N m', low=0, high=0.01, low_open=True)
    warm_max_iterations: int = setting(
        15, 'proxsuite outer-iteration limit of a warm-started solve before the cold retry.',
        low=1, high=1000000)
    max_iterations: int = setting(
        200, 'proxsuite outer-iteration limit of a cold solve.', low=1, high=1000000)
    max_inner_iterations: int = setting(
        10, 'proxsuite inner iterations per outer one; healthy solves use 1-2.',
        low=1, high=1000000)

    def __post_init__(self):
        """Validate every field; raise ConfigError naming the field, value and range."""
        check_settings(self)
        check_range('max_normal_force', self.max_normal_force, self.min_normal_force,
                    NORMAL_FORCE_LIMIT, 'N', low_open=True)
        check_range('squeeze_force', self.squeeze_force, 0.0, self.max_normal_force, 'N')


@dataclasses.dataclass(frozen=True)
class WrenchQPResult:
    """
    Solution of eq. 10.

    wrenches: {'left', 'right'} -> (6,) [f; m] applied by the pad on the object, world frame,
        moment about the contact point [N, N m]; the robot pushes with +f.
    slack: (6,) f_o^d - G f, the part of the desired object wrench not produced [N, N m].
    slack_norm: ||slack||; feasible: slack_norm <= slack_tolerance.
    in_contact: {'left', 'right'} -> bool, pad within the contact distance.
    status: proxsuite status name; iterations: proxsuite iterations of this call (a warm
        attempt and its cold retry add up).
    """

    wrenches: dict
    slack: np.ndarray
    slack_norm: float
    feasible: bool
    in_contact: dict
    status: str
    iterations: int


def pad_frame_constraint_matrix(config):
    """
    Return the (11, 6) rows S of the contact constraints on a pad-frame wrench [f; m].

    Row 0 is the normal force f_z (two-sided bounds); rows 1-10 are S w <= 0: friction
    pyramid (4), torsion (2) and centre of pressure (4).
    """
    k = config.friction_coefficient / math.sqrt(2.0)
    gamma = config.torsion_arm
    half_length = config.pad_half_length
    half_width = config.pad_half_width
    return np.array([
        [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
        [1.0, 0.0, -k, 0.0, 0.0, 0.0],
        [-1.0, 0.0, -k, 0.0, 0.0, 0.0],
        [0.0, 1.0, -k, 0.0, 0.0, 0.0],
        [0.0, -1.0, -k, 0.0, 0.0, 0.0],
        [0.0, 0.0, -gamma, 0.0, 0.0, 1.0],
        [0.0, 0.0, -gamma, 0.0, 0.0, -1.0],
        [0.0, 0.0, -half_width, 1.0, 0.0, 0.0],
        [0.0, 0.0, -half_width, -1.0, 0.0, 0.0],
        [0.0, 0.0, -half_length, 0.0, 1.0, 0.0],
        [0.0, 0.0, -half_length, 0.0, -1.0, 0.0],
    ])


class ContactWrenchQP:
    """
    Stateful solver of eq. 10: one proxsuite dense QP, updated and warm-started every tick.

    The QP object is created here and initialised (Hessian, equilibration) with the first real
    problem; afterwards it is only updated. A solve starts from the previous primal-dual
    solution (InitialGuess.WARM_START_WITH_PREVIOUS_RESULT) unless a pad changed contact state
    since the last solve, or this is the first solve (proxsuite 0.8 crashes on a warm start
    without previous results): those start from the equality-constrained cold guess, which
    also resets the proximal parameters. The problem is feasible by construction (the slack
    absorbs any balance error), so proxsuite's infeasibility checks are disabled (they fired
    spuriously after warm starts in testing), and a warm solve that does not converge within
    warm_max_iterations is repeated once cold before SolverError is raised. Rarely (and
    depending on memory alignment, so not reproducibly) a warm solve stalls in proxsuite's
    inner loop; with its default of 1500 inner iterations per outer one that cost 180 ms,
    max_inner_iterations bounds it to about 1 ms before the cold retry.
    """

    def __init__(self, config=None):
        """Create the QP and the constant parts of its data."""
        self.config = WrenchQPConfig() if config is None else config
        cfg = self.config
        wrench_weights = np.tile([cfg.force_weight] * 3 + [cfg.moment_weight] * 3, 2)
        balance_weights = np.array([cfg.balance_force_weight] * 3
                                   + [cfg.balance_moment_weight] * 3)
        self._hessian = np.diag(np.concatenate(
            (2.0 * wrench_weights, 2.0 * balance_weights, np.zeros(_N_SLACK))))
        self._gradient = np.zeros(_N_VARIABLES)
        self._gradient[_SLACK_BOUND] = ([cfg.balance_force_l1_weight] * 3
                                        + [cfg.balance_moment_l1_weight] * 3)
        self._squeeze_gradient = -2.0 * cfg.force_weight * cfg.squeeze_force
        self._equality = np.zeros((6, _N_VARIABLES))
        self._equality[:, _SLACK] = np.eye(_N_SLACK)
        self._b = np.zeros(6)
        self._inequality = np.zeros((_N_INEQUALITIES, _N_VARIABLES))
        slack_rows = slice(2 * _N_PAD_ROWS, _N_INEQUALITIES)
        self._inequality[slack_rows, _SLACK] = np.vstack((np.eye(_N_SLACK), -np.eye(_N_SLACK)))
        self._inequality[slack_rows, _SLACK_BOUND] = np.vstack(
            (-np.eye(_N_SLACK), -np.eye(_N_SLACK)))
        self._lower = np.full(_N_INEQUALITIES, -np.inf)
        self._upper = np.zeros(_N_INEQUALITIES)
        self._contact_rows = pad_frame_constraint_matrix(cfg)
        self._contact_lower = np.full(_N_PAD_ROWS, -np.inf)
        self._contact_lower[0] = cfg.min_normal_force
        self._contact_upper = np.zeros(_N_PAD_ROWS)
        self._contact_upper[0] = cfg.max_normal_force
        self._qp = proxsuite.proxqp.dense.QP(_N_VARIABLES, 6, _N_INEQUALITIES)
        settings = self._qp.settings
        settings.eps_abs = cfg.solver_tolerance
        settings.eps_rel = 0.0
        settings.verbose = False
        settings.frequence_infeasibility_check = _NEVER
        settings.eps_primal_inf = 1e-12
        settings.eps_dual_inf = 1e-12
        settings.max_iter_in = int(cfg.max_inner_iterations)
        self._initialised = False
        self._warm_start_selected = None
        self._last_contact_state = None

    def problem(self):
        """Return copies of the last QP data {H, g, A, b, C, l, u} (x = [w_L, w_R, s, t])."""
        return {'H': self._hessian.copy(), 'g': self._gradient.copy(),
                'A': self._equality.copy(), 'b': self._b.copy(),
                'C': self._inequality.copy(), 'l': self._lower.copy(),
                'u': self._upper.copy()}

    def contact_wrenches(self, object_wrench, p_world_object, contacts):
        """
        Return the WrenchQPResult distributing object_wrench over the two pads (eq. 10).

        object_wrench: (6,) desired net wrench f_o^d on the object, world frame, moment about
            p_world_object [N, N m].
        p_world_object: (3,) object centre of mass [m].
        contacts: {'left': PadContact, 'right': PadContact}.
        Raises InputError for non-finite or misshaped inputs, SolverError when proxsuite does
        not solve.
        """
        cfg = self.config
        missing = [arm for arm in PAD_ORDER if arm not in contacts]
        if missing:
            raise InputError(f'contacts lacks {missing}; expected keys {PAD_ORDER}')
        left, right = contacts['left'], contacts['right']
        arrays = (np.asarray(object_wrench, dtype=float), np.asarray(p_world_object, dtype=float),
                  np.asarray(left.p_world_contact, dtype=float),
                  np.asarray(left.R_world_pad, dtype=float),
                  np.asarray(left.normal_distance, dtype=float),
                  np.asarray(right.p_world_contact, dtype=float),
                  np.asarray(right.R_world_pad, dtype=float),
                  np.asarray(right.normal_distance, dtype=float))
        for array, shape, name in zip(arrays, _INPUT_SHAPES, _INPUT_NAMES):
            if array.shape != shape:
                raise InputError(f'{name} must have shape {shape}, got {array.shape}')
        if not np.isfinite(np.concatenate([a.ravel() for a in arrays])).all():
            bad = [name for array, name in zip(arrays, _INPUT_NAMES)
                   if not np.isfinite(array).all()]
            raise InputError('wrench QP input not finite: ' + ', '.join(bad))
        self._b = arrays[0]
        p_world_object = arrays[1]
        contact_state = (bool(arrays[4] <= cfg.contact_distance),
                         bool(arrays[7] <= cfg.contact_distance))
        cold = contact_state != self._last_contact_state
        rotations = (arrays[3], arrays[6])
        for index, (p_world_contact, R_world_pad) in enumerate(((arrays[2], arrays[3]),
                                                                (arrays[5], arrays[6]))):
            column = 6 * index
            block = self._equality[:, column:column + 6]
            block[0:3, 0:3] = R_world_pad
            block[3:6, 3:6] = R_world_pad
            block[3:6, 0:3] = skew(p_world_contact - p_world_object) @ R_world_pad
        if cold:
            self._set_contact_rows(contact_state)
        status, iterations = self._solve(cold)
        self._last_contact_state = contact_state
        solution = self._qp.results.x
        wrenches = {}
        for index, arm in enumerate(PAD_ORDER):
            force_and_moment = solution[6 * index:6 * index + 6].reshape(2, 3)
            wrench = (force_and_moment @ rotations[index].T).ravel()
            wrench.flags.writeable = False
            wrenches[arm] = wrench
        slack = solution[_SLACK].copy()
        slack.flags.writeable = False
        slack_norm = math.sqrt(slack @ slack)
        return WrenchQPResult(
            wrenches=wrenches, slack=slack, slack_norm=slack_norm,
            feasible=slack_norm <= cfg.slack_tolerance,
            in_contact={'left': contact_state[0], 'right': contact_state[1]},
            status=status, iterations=iterations)

    def _set_contact_rows(self, contact_state):
        """Write each pad's contact rows, bounds and squeeze preference for its state."""
        for index, touching in enumerate(contact_state):
            rows = slice(_N_PAD_ROWS * index, _N_PAD_ROWS * (index + 1))
            columns = slice(6 * index, 6 * index + 6)
            self._inequality[rows, columns] = (
                self._contact_rows if touching else _RELEASED_PAD_ROWS)
            self._lower[rows] = self._contact_lower if touching else _RELEASED_PAD_LOWER
            self._upper[rows] = self._contact_upper if touching else _RELEASED_PAD_UPPER
            self._gradient[6 * index + 2] = self._squeeze_gradient if touching else 0.0

    def _solve(self, cold):
        """Update and solve (warm unless cold), retrying once cold; return (status, iter)."""
        qp = self._qp
        if not self._initialised:
            qp.init(self._hessian, self._gradient, self._equality, self._b,
                    self._inequality, self._lower, self._upper)
            self._initialised = True
            cold = True
        elif cold:
            qp.update(g=self._gradient, A=self._equality, b=self._b, C=self._inequality,
                      l=self._lower, u=self._upper)
        else:
            qp.update(A=self._equality, b=self._b)
        iterations = 0
        if not cold:
            self._set_start(warm=True)
            qp.solve()
            info = qp.results.info
            iterations = info.iter
            cold = not self._solved(info)
        if cold:
            self._set_start(warm=False)
            qp.solve()
            info = qp.results.info
            iterations += info.iter
            if not self._solved(info):
                self._last_contact_state = None
                status = info.status.name
                raise SolverError(f'wrench QP not solved: {status} after {iterations} '
                                  f'iterations', status=status, problem=self.problem())
        return info.status.name, iterations

    def _set_start(self, warm):
        """Select the warm (previous result) or cold (equality-constrained) initial guess."""
        if warm != self._warm_start_selected:
            settings = self._qp.settings
            settings.initial_guess = _WARM_START if warm else _COLD_START
            settings.max_iter = int(self.config.warm_max_iterations if warm
                                    else self.config.max_iterations)
            self._warm_start_selected = warm

    def _solved(self, info):
        """Return True if the last solve reported PROXQP_SOLVED with a finite solution."""
        return info.status == _SOLVED and math.isfinite(float(np.sum(self._qp.results.x)))
