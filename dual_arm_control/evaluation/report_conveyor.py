"""
The conveyor section of docs/results.md: tosses into the container a belt carries (issue 15).

Reads RESULTS/conveyor_toss/summary.json and its plots, written by
`dual_arm_eval --scenario conveyor_toss --trials 100 --runner inprocess --out
docs/results/conveyor_toss`, and the graph run's metrics in RESULTS/conveyor_toss/graph/
(`dual_arm_bringup --scenario config/scenarios/conveyor_toss.yaml`).
"""

from pathlib import Path

from dual_arm_control.evaluation.report_format import image_links, MISSING, number, table
from dual_arm_control.evaluation.report_sections import failure_modes

CONVEYOR_FOLDER = 'conveyor_toss'
CONVEYOR_METRICS = ('landing_error_in_container', 'contact_time_gap', 'max_slip',
                    'impact_speed_left', 'impact_speed_right', 'cycle_time')


def load_conveyor(results_dir, read):
    """Return (summary or None, graph metrics or None, plot paths) of the conveyor batch."""
    folder = Path(results_dir) / CONVEYOR_FOLDER
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
    metrics = summary.get('metrics', {})
    rows = [(key, *(number(metrics[key].get(stat), 4) for stat in ('median', 'p95', 'max')),
             metrics[key].get('count', MISSING))
            for key in CONVEYOR_METRICS if key in metrics]
    modes = failure_modes(summary.get('failures', []))
    out += ['`dual_arm_eval --scenario conveyor_toss --trials 100 --runner inprocess --jobs 1 '
            '--out docs/results/conveyor_toss`; the graph run: `dual_arm_bringup --scenario '
            'config/scenarios/conveyor_toss.yaml`.', '',
            f'Scenario `{summary.get("scenario")}` (belt 0.1-0.4 m/s with a +-20 % sinusoidal '
            'speed disturbance, container start and belt start drawn per trial), '
            f'{summary.get("trials")} trials, runner {summary.get("runner")}, seed '
            f'{summary.get("seed")}: success rate '
            f'{number(summary.get("success_rate"), 1, 100.0, "%")}, box in the container '
            f'{number(landed_share(summary), 1, 100.0, "%")}.', '',
            table(('metric', 'median', 'p95', 'max', 'count'), rows), '',
            'landing_error_in_container: horizontal distance of the box centre from the '
            "container centre when the box's bottom comes down to the rim [m]; cycle_time "
            'includes the wait at standby for the container [s].', '',
            'Failure modes (first reason of each failed trial): '
            + ('none' if not modes else '; '.join(f'{mode}: {count}'
                                                  for mode, count in modes)) + '.', '']
    if graph is not None:
        out += ['Node graph (`dual_arm_bringup`, lockstep), nominal scenario: success '
                f'{graph.get("success")}, landed in the container '
                f'{graph.get("landed_in_container")}, distance to the container centre '
                f'{number(graph.get("landing_error_in_container"), 1, 1000.0, "mm")}.', '']
    return out + image_links(plots, link_root) + ['']
