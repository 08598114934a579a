"""
The conveyor section of docs/results.md: tosses into the container a belt carries (issue 15).

Reads RESULTS/conveyor_toss/summary.json and its plots, written by
`dual_arm_eval --scenario conveyor_toss --trials 100 --runner inprocess --out
docs/results/conveyor_toss`, and the graph run's metrics in RESULTS/conveyor_toss/graph/
(`dual_arm_bringup --scenario config/scenarios/conveyor_toss.yaml`).
"""

from pathlib import Path

from dual_arm_control.evaluation.report_format import (failure_mode_sentence, image_links, number,
                                                       statistics_table)

CONVEYOR_FOLDER = 'conveyor_toss'
CONVEYOR_METRICS = ('landing_error_in_container', 'contact_time_gap', 'max_slip',
                    'impact_speed_left', 'impact_speed_right', 'cycle_time')


def load_batch(results_dir, name, read):
    """Return (summary or None, graph metrics or None, plot paths) of the batch folder name."""
    folder = Path(results_dir) / name
    plots = [path.relative_to(results_dir).as_posix() for path in sorted(folder.glob('*.png'))]
    return read(folder / 'summary.json'), read(folder / 'graph' / 'metrics.json'), plots


def landed_share(summary):
    """Return the share of all trials whose box ended in the container, or None."""
    landed = summary.get('true_counts', {}).get('landed_in_container')
    trials = summary.get('trials')
    return None if landed is None or not trials else landed / trials


def conveyor_section(results, link_root):
    """Section 6: success, distance to the container centre, failure modes, plots."""
    summary, graph, plots = results.get('conveyor', (None, None, []))
    out = ['## 6. Toss into a moving container (issue 15)', '']
    if summary is None:
        return out + [f'_Not run: `{CONVEYOR_FOLDER}/summary.json` is missing._', '']
    out += ['`dual_arm_eval --scenario conveyor_toss --trials 100 --runner inprocess --jobs 1 '
            '--out docs/results/conveyor_toss`; the graph run: `dual_arm_bringup --scenario '
            'config/scenarios/conveyor_toss.yaml`.', '',
            f'Scenario `{summary.get("scenario")}` (belt 0.1-0.4 m/s with a +-20 % sinusoidal '
            'speed disturbance, container start and belt start drawn per trial), '
            f'{summary.get("trials")} trials, runner {summary.get("runner")}, seed '
            f'{summary.get("seed")}: success rate '
            f'{number(summary.get("success_rate"), 1, 100.0, "%")}, box in the container '
            f'{number(landed_share(summary), 1, 100.0, "%")}.', '',
            statistics_table(summary.get('metrics', {}), CONVEYOR_METRICS,
                             ('median', 'p95', 'max')), '',
            'landing_error_in_container: horizontal distance of the box centre from the '
            "container centre when the box's bottom comes down to the rim [m]; cycle_time "
            'includes the wait at standby for the container [s].', '',
            failure_mode_sentence(summary.get('failures', [])), '']
    if graph is not None:
        out += ['Node graph (`dual_arm_bringup`, lockstep), nominal scenario: success '
                f'{graph.get("success")}, landed in the container '
                f'{graph.get("landed_in_container")}, distance to the container centre '
                f'{number(graph.get("landing_error_in_container"), 1, 1000.0, "mm")}.', '']
    return out + image_links(plots, link_root) + ['']
