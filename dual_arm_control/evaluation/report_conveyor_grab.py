"""
The conveyor grab subsection of docs/results.md: the box grabbed from the incoming belt.

Reads RESULTS/conveyor_grab/summary.json and its plots, written by
`dual_arm_eval --scenario conveyor_grab --trials 100 --runner inprocess --out
docs/results/conveyor_grab`, and the graph run's metrics in RESULTS/conveyor_grab/graph/
(`dual_arm_bringup --scenario config/scenarios/conveyor_grab.yaml`).
"""

from dual_arm_control.evaluation.report_format import (failure_mode_sentence, image_links, number,
                                                       statistics_table)

GRAB_FOLDER = 'conveyor_grab'
GRAB_METRICS = ('contact_time_gap', 'impact_speed_relative_left', 'impact_speed_relative_right',
                'belt_drag', 'max_slip', 'landing_error', 'release_velocity_error',
                'cycle_time')


def conveyor_grab_section(results, link_root):
    """Section 6b: success, contact gap, relative impact speeds, drag, failure modes, plots."""
    summary, graph, plots = results.get('conveyor_grab', (None, None, []))
    out = ['### 6b. Grab from the moving incoming belt (issue 15)', '']
    if summary is None:
        return out + [f'_Not run: `{GRAB_FOLDER}/summary.json` is missing._', '']
    out += ['`dual_arm_eval --scenario conveyor_grab --trials 100 --runner inprocess --jobs 1 '
            '--out docs/results/conveyor_grab`; the graph run: `dual_arm_bringup --scenario '
            'config/scenarios/conveyor_grab.yaml`.', '',
            f'Scenario `{summary.get("scenario")}` (the paper cube on the incoming belt at '
            '0.1-0.3 m/s with a +-20 % sinusoidal speed disturbance, box start and belt start '
            f'drawn per trial, tossed as in paper_toss), {summary.get("trials")} trials, runner '
            f'{summary.get("runner")}, seed {summary.get("seed")}: success rate '
            f'{number(summary.get("success_rate"), 1, 100.0, "%")} (grasp: contact gap <= '
            '10 ms, both relative impact speeds within 15 % of 0.5 m/s, belt drag <= 1 cm; '
            'toss: the paper_toss criteria).', '',
            statistics_table(summary.get('metrics', {}), GRAB_METRICS,
                             ('median', 'p95', 'min', 'max')), '',
            'impact_speed_relative_*: tool velocity before its contact minus the box velocity '
            "before the first contact, along the impact direction [m/s]; belt_drag: the box's "
            'motion along the belt relative to the belt surface between the first contact and '
            'both pads in contact [m]; cycle_time includes the wait at standby for the box [s].',
            '', failure_mode_sentence(summary.get('failures', [])), '']
    if graph is not None:
        out += ['Node graph (`dual_arm_bringup`, lockstep), nominal scenario: success '
                f'{graph.get("success")}, contact gap '
                f'{number(graph.get("contact_time_gap"), 1, 1000.0, "ms")}, relative impact '
                f'speeds {number(graph.get("impact_speed_relative_left"), 3)} / '
                f'{number(graph.get("impact_speed_relative_right"), 3)} m/s, belt drag '
                f'{number(graph.get("belt_drag"), 1, 1000.0, "mm")}, landing error '
                f'{number(graph.get("landing_error"), 1, 1000.0, "mm")}.', '']
    return out + image_links(plots, link_root) + ['']
