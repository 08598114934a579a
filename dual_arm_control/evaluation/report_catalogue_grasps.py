"""
The catalogue_grasps subsection of docs/results.md: each catalogue box tossed and placed.

Reads RESULTS/catalogue_grasps/results.json (`dual_arm_experiment catalogue_grasps`).
"""

from dual_arm_control.evaluation.report_format import MISSING, not_run, number, table

NAME = 'catalogue_grasps'


def catalogue_grasps_section(results, link_root):
    """Section 4c: per box and task the outcome, slip and the friction cones' worst use."""
    out = ['## 4c. Each catalogue box at its mass through the node graph', '']
    run = results.get(NAME)
    if run is None:
        return out + [not_run(NAME)]
    out += ['`dual_arm_experiment catalogue_grasps`: every box of `config/objects.yaml` in '
            'place of the paper cube of `paper_toss` and `paper_place` (centred, its catalogue '
            'size, mass and friction), run through `dual_arm_bringup` (node graph, lockstep, '
            'topics recorded). Friction ratios are the largest |f_t| / (mu f_n) of a pad while '
            'the box is held (below 1: inside the cone; 1 minus the ratio is the margin): '
            "planned, the wrench QP's pad wrenches (the `contact_wrench` topics) against the "
            "QP's design friction mu "
            f'{number(run.get("qp_friction_coefficient"), 2)} (its pyramid allows 0.71 along '
            "one tangent, 1 at its corners) and against the box's; measured, the MuJoCo "
            "contact force of the pad on the box against the box's friction.", '']
    rows = [(row['object'], row['task'], number(row['mass'], 1, unit='kg'),
             number(row['friction'], 2), 'yes' if row['success'] else 'no',
             number(row['max_slip'], 1, 1000.0, 'mm'),
             number(row['contact_time_gap'], 0, 1000.0, 'ms'),
             number(row['planned_friction_ratio_design'], 2),
             number(row['planned_friction_ratio'], 2),
             number(row['measured_friction_ratio'], 2),
             number(row['measured_friction_ratio_p95'], 2)) for row in run.get('runs', [])]
    out += [table(('box', 'scenario', 'mass', 'mu', 'success', 'slip', 'contact gap',
                   'planned / design mu', 'planned / box mu', 'measured / box mu',
                   'measured p95'), rows), '']
    planned = [row['planned_friction_ratio'] for row in run.get('runs', [])]
    measured = [row['measured_friction_ratio'] for row in run.get('runs', [])
                if row['measured_friction_ratio'] is not None]
    out += ['Worst ratio over the runs: planned '
            + (number(max(planned), 2) if planned else MISSING) + ', measured '
            + (number(max(measured), 2) if measured else MISSING) + '.', '']
    return out
