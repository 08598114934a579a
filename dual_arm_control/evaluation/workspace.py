"""
Reachable space of the dual-arm cell and of tossing, as top-view areas (paper Figure 8).

Method (experiment 2, docs/results.md):

- Each arm's pad-facing reachable positions: joint configurations sampled uniformly within the
  joint limits (fixed seed); for each, joint A1 (a vertical axis through the base) is turned so
  the horizontal part of the pad normal (tool z) points across the cell (left: -y, right: +y),
  as it must to squeeze the object's +-y faces. Turning A1 moves the tool on a circle about
  the base axis, so the turned configuration's tool position follows without new kinematics;
  it is kept when A1 stays within its limit and the pad normal is within `max_tilt` of the
  horizontal.
- The joint reachable space: object-centre positions c where the left tool can be at
  c + (0, w/2, 0) and the right tool at c - (0, w/2, 0) in the same height slab (w = the
  object's width along the squeeze axis), for slabs covering a height band; its top view on a
  fixed grid (grid occupancy: a cell counts when tool samples fall in the two offset cells).
- The tossing reachable space: the convex hull of the measured landing positions, on the same
  grid (a cell counts when its centre lies in the hull). Extension = area of the hull cells
  outside the joint reachable space / joint reachable area * 100.
"""

from dataclasses import dataclass
import math

from dual_arm_control.core.exceptions import InputError
from dual_arm_control.core.validation import check_range
import numpy as np

PAD_NORMALS = {'left': np.array([0.0, -1.0, 0.0]), 'right': np.array([0.0, 1.0, 0.0])}
"""Horizontal direction the pad normal must point along to squeeze the object (world)."""


@dataclass(frozen=True)
class Grid:
    """
    A fixed top-view grid: lower corner (x0, y0) [m], square cells of `cell` [m], nx by ny.

    Cell (i, j) covers [x0 + i cell, x0 + (i + 1) cell) x [y0 + j cell, y0 + (j + 1) cell).
    """

    x0: float
    y0: float
    cell: float
    nx: int
    ny: int

    def __post_init__(self):
        check_range('cell', self.cell, 0.0, 1.0, 'm', low_open=True)
        check_range('nx', self.nx, 1, 100000)
        check_range('ny', self.ny, 1, 100000)

    @property
    def cell_area(self):
        """Area of one cell [m^2]."""
        return self.cell * self.cell

    def centres(self):
        """Return the cell centres as ((nx,) x [m], (ny,) y [m])."""
        return (self.x0 + (np.arange(self.nx) + 0.5) * self.cell,
                self.y0 + (np.arange(self.ny) + 0.5) * self.cell)

    def indices(self, points_xy):
        """Return integer (i, j) arrays of the cells holding points (N, 2) and an inside mask."""
        points_xy = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        i = np.floor((points_xy[:, 0] - self.x0) / self.cell).astype(int)
        j = np.floor((points_xy[:, 1] - self.y0) / self.cell).astype(int)
        inside = (i >= 0) & (i < self.nx) & (j >= 0) & (j < self.ny)
        return i, j, inside


def occupancy(points_xy, grid):
    """Return the (nx, ny) bool mask of grid cells holding at least one of points_xy (N, 2)."""
    mask = np.zeros((grid.nx, grid.ny), dtype=bool)
    i, j, inside = grid.indices(points_xy)
    mask[i[inside], j[inside]] = True
    return mask


def mask_area(mask, grid):
    """Return the area [m^2] of the true cells of a grid mask."""
    return float(np.count_nonzero(mask)) * grid.cell_area


def convex_hull(points_xy):
    """
    Return the convex hull of points (N, 2) as vertices (M, 2) in counter-clockwise order.

    Andrew's monotone chain; collinear points on the boundary are dropped. Fewer than three
    distinct, non-collinear points give a degenerate hull (the points themselves).
    """
    points = sorted(set(map(tuple, np.asarray(points_xy, dtype=float).reshape(-1, 2))))
    if len(points) < 3:
        return np.array(points, dtype=float).reshape(-1, 2)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for point in points:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], point) <= 0.0:
            lower.pop()
        lower.append(point)
    for point in reversed(points):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], point) <= 0.0:
            upper.pop()
        upper.append(point)
    return np.array(lower[:-1] + upper[:-1], dtype=float)


def polygon_area(vertices):
    """Return the area [m^2] of a simple polygon (M, 2) (shoelace formula)."""
    vertices = np.asarray(vertices, dtype=float).reshape(-1, 2)
    if len(vertices) < 3:
        return 0.0
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def polygon_mask(vertices, grid):
    """Return the (nx, ny) mask of cells whose centre lies inside a convex polygon (CCW)."""
    vertices = np.asarray(vertices, dtype=float).reshape(-1, 2)
    if len(vertices) < 3:
        return np.zeros((grid.nx, grid.ny), dtype=bool)
    xs, ys = grid.centres()
    x, y = np.meshgrid(xs, ys, indexing='ij')
    inside = np.ones(x.shape, dtype=bool)
    for start, end in zip(vertices, np.roll(vertices, -1, axis=0)):
        edge = end - start
        inside &= edge[0] * (y - start[1]) - edge[1] * (x - start[0]) >= 0.0
    return inside


def extension_percent(joint_mask, toss_mask):
    """
    Return (added mask, extension [%]) of the tossing space over the joint reachable space.

    added = toss cells outside the joint space; extension = |added| / |joint| * 100.
    """
    joint_mask = np.asarray(joint_mask, dtype=bool)
    added = np.asarray(toss_mask, dtype=bool) & ~joint_mask
    joint = np.count_nonzero(joint_mask)
    if joint == 0:
        raise InputError('the joint reachable space is empty: no extension to compute')
    return added, 100.0 * np.count_nonzero(added) / joint


def joint_reachable_mask(left_tool_positions, right_tool_positions, half_width, grid,
                         z_band, slab_height):
    """
    Return the top-view mask of object centres both pads can reach (see the module docstring).

    left/right_tool_positions: (N, 3) pad-facing reachable tool positions [m]; half_width:
    half the object's width along the squeeze axis (world y) [m]; z_band: (low, high) tool
    heights considered [m], cut into slabs of slab_height [m]; the two tools must share a slab.
    """
    low, high = float(z_band[0]), float(z_band[1])
    if not high > low:
        raise InputError(f'z_band must have high > low, got {z_band}')
    check_range('slab_height', slab_height, 0.0, high - low + 1e-9, 'm', low_open=True)
    edges = np.arange(low, high + 1e-9, slab_height)
    if edges[-1] < high - 1e-9:
        edges = np.append(edges, high)
    offset = np.array([0.0, half_width, 0.0])
    joint = np.zeros((grid.nx, grid.ny), dtype=bool)
    left = np.asarray(left_tool_positions, dtype=float).reshape(-1, 3) - offset
    right = np.asarray(right_tool_positions, dtype=float).reshape(-1, 3) + offset
    for bottom, top in zip(edges[:-1], edges[1:]):
        in_left = (left[:, 2] >= bottom) & (left[:, 2] < top)
        in_right = (right[:, 2] >= bottom) & (right[:, 2] < top)
        joint |= occupancy(left[in_left, :2], grid) & occupancy(right[in_right, :2], grid)
    return joint


def pad_alignment_turns(normals, axis, target):
    """
    Return the rotations (N,) [rad] about the unit axis that point each normal at the target.

    Only a normal's part perpendicular to the axis is aligned with the target direction;
    counter-clockwise about the axis is positive.
    """
    normals = np.asarray(normals, dtype=float).reshape(-1, 3)
    axis = np.asarray(axis, dtype=float)
    horizontal = normals - (normals @ axis)[:, None] * axis
    return np.arctan2(np.cross(horizontal, target) @ axis, horizontal @ target)


def turned_positions(positions, base, axis, turns):
    """Return positions (N, 3) rotated by turns (N,) [rad] about the line base + s axis."""
    relative = np.asarray(positions, dtype=float).reshape(-1, 3) - base
    cos, sin = np.cos(turns)[:, None], np.sin(turns)[:, None]
    along = (relative @ axis)[:, None] * axis
    return base + relative * cos + np.cross(axis, relative) * sin + along * (1.0 - cos)


def pad_facing_tool_positions(model, arm, count, rng, max_tilt):
    """
    Return (N, 3) tool positions [m] of `arm` reachable with the pad facing across the cell.

    model: the arm's ArmModel (pinocchio, world frame); count: joint configurations sampled
    uniformly within the limits; rng: numpy Generator; max_tilt: largest angle between the pad
    normal and the horizontal [rad]. Each sample's A1 is turned to align the pad normal's
    horizontal part with PAD_NORMALS[arm]; samples whose turned A1 leaves its limits, or whose
    normal is too steep, are dropped.
    """
    check_range('max_tilt', max_tilt, 0.0, 0.5 * math.pi, 'rad')
    lower, upper = model.position_limits
    axis = model.T_world_base.rotation[:, 2]
    base = model.T_world_base.translation
    samples = rng.uniform(lower, upper, size=(int(count), model.nq))
    positions = np.empty((len(samples), 3))
    normals = np.empty((len(samples), 3))
    for index, q in enumerate(samples):
        positions[index], R_world_tool = model.tool_pose(q)
        normals[index] = R_world_tool[:, 2]
    turns = pad_alignment_turns(normals, axis, PAD_NORMALS[arm])
    keep = ((np.abs(normals @ axis) <= math.sin(max_tilt)) & (samples[:, 0] + turns >= lower[0])
            & (samples[:, 0] + turns <= upper[0]))
    return turned_positions(positions[keep], base, axis, turns[keep])
