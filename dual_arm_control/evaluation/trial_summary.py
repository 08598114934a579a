"""
What dual_arm_eval's trials left: one outcome per trial, the batch statistics, failure reasons.

summarize() aggregates the per-episode metrics (evaluation/episode.py); failure_reason() names
the success criteria a finished trial missed.
"""

from dataclasses import dataclass

from dual_arm_control.core.arms import ARMS
from dual_arm_control.evaluation.episode import (CONTACT_GAP_LIMIT, LANDING_LIMIT, PLACE_LIMIT,
                                                 PLACE_SPEED_LIMIT, PLACE_TILT_LIMIT,
                                                 RELEASE_ORIENTATION_LIMIT,
                                                 RELEASE_POSITION_LIMIT, RELEASE_VELOCITY_LIMIT,
                                                 SLIP_LIMIT)
from dual_arm_control.evaluation.grab_metrics import grab_misses
from dual_arm_control.scenario import PLACE_TASKS, TOSS_TASKS
import numpy as np


# A tool that never moved farther than this from its start did not reach [m].
STANDBY_DRIFT = 0.01
# Both pads off the box this long before the task let go: it was lost in the carry [s] (a
# release leaves the pads within the hands' opening, 4 ms after the task lets go in paper_toss).
LOST_BOX_LEAD = 0.02


@dataclass(frozen=True)
class TrialOutcome:
    """What one trial left: its metrics dict, or None and the reason it produced none."""

    index: int
    metrics: object = None
    error: object = None


def succeeded(outcome):
    """Return True if the trial produced metrics and they say success."""
    return outcome.metrics is not None and outcome.metrics.get('success') is True


def _numeric(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def summarize(metrics_list):
    """
    Aggregate the trials' metrics: return {'trials', 'success_rate', 'metrics', 'true_counts'}.

    metrics_list holds one metrics dict per trial, or None for a trial that produced none (it
    counts as a failure). success_rate = trials with success true / all trials. For every key
    whose non-null values are all numbers (bools excluded), 'metrics' gives mean, median, p95
    (numpy percentile, linear interpolation), min and max over the trials where it is not
    null, and count = the number of those trials; for every key whose non-null values are all
    bools but success, 'true_counts' gives how many trials have it true (e.g. landed_in_container).
    Keys keep the order they first appear in.
    """
    trials = len(metrics_list)
    present = [metrics for metrics in metrics_list if metrics]
    successes = sum(1 for metrics in present if metrics.get('success') is True)
    values = {}
    for metrics in present:
        for key, value in metrics.items():
            if value is not None:
                values.setdefault(key, []).append(value)
    statistics = {}
    true_counts = {key: sum(items) for key, items in values.items() if key != 'success'
                   and all(isinstance(item, bool) for item in items)}
    for key, items in values.items():
        if not all(_numeric(item) for item in items):
            continue
        array = np.array(items, dtype=float)
        statistics[key] = {'mean': float(array.mean()), 'median': float(np.median(array)),
                           'p95': float(np.percentile(array, 95)), 'min': float(array.min()),
                           'max': float(array.max()), 'count': int(array.size)}
    return {'trials': trials, 'success_rate': successes / trials if trials else None,
            'metrics': statistics, 'true_counts': true_counts}


def _exceeds(key, value, limit, unit):
    """Return 'key value > limit unit'; the value in full when it rounds to the limit."""
    text = f'{value:.4g}'
    if float(text) <= limit:
        text = repr(value)
    return f'{key} {text} > {limit:g}{" " + unit if unit else ""}'


def _grab_reason(key, value, limit, unit, detail):
    """Return the text of one missed grab criterion (grab_metrics.grab_misses)."""
    if value is None:
        return f'no {key}'
    return _exceeds(key, value, limit, unit) + ('' if detail is None else f' ({detail})')


def failure_reason(task, metrics, grab_impact_speed=None):
    """
    Return why a finished trial of task failed its success criteria (evaluation/episode.py).

    grab_impact_speed: the desired impact speed [m/s] of a grab from the moving incoming belt,
    whose relative impact speeds and belt drag are then checked too; None for a resting box.
    """
    reasons = []
    collisions = metrics.get('arm_collision_count')
    if collisions:
        first = metrics.get('first_arm_collision') or {}
        reasons.append(f'{collisions} arm collisions (first: {" - ".join(first.get("geoms", []))} '
                       f'at {first.get("t", float("nan")):.3f} s)')
    gap = metrics.get('contact_time_gap')
    drifts = [metrics.get(f'max_tool_drift_{arm}') for arm in ARMS]
    if gap is None and metrics.get('start_refusal'):
        reasons.append(f'refused before the reach: {metrics["start_refusal"]}')
    elif gap is None and all(drift is not None and drift < STANDBY_DRIFT for drift in drifts):
        reasons.append('no reach: the arms stayed at standby (' + (
            'the container never came in range, or the grasp was refused'
            if task in TOSS_TASKS else 'grasp refused as out of reach') + ')')
    elif gap is None:
        reasons.append('no contact of both pads')
    elif gap > CONTACT_GAP_LIMIT:
        reasons.append(_exceeds('contact_time_gap', gap, CONTACT_GAP_LIMIT, 's'))
    if gap is not None and metrics.get('t_grasp') is None:
        reasons.append('no sustained grasp')
    left, let_go = metrics.get('t_release'), metrics.get('t_task_release')
    if left is not None and let_go is not None and let_go - left >= LOST_BOX_LEAD:
        reasons.append(f'box lost in the carry: both pads off {let_go - left:.3f} s before the '
                       'task let go')
    if grab_impact_speed is not None and gap is not None:
        reasons.extend(_grab_reason(*miss) for miss in grab_misses(metrics, grab_impact_speed))
    checks = [('max_slip', SLIP_LIMIT, 'm')]
    if task in TOSS_TASKS:
        checks += [('release_position_error', RELEASE_POSITION_LIMIT, 'm'),
                   ('release_velocity_error', RELEASE_VELOCITY_LIMIT, ''),
                   ('landing_error', LANDING_LIMIT, 'm'),
                   ('release_orientation_error', RELEASE_ORIENTATION_LIMIT, 'deg')]
        if metrics.get('t_grasp') is not None and metrics.get('t_release') is None:
            reasons.append('no release')
        elif metrics.get('landed_in_container') is True:
            pass
        elif metrics.get('landed_in_container') is False:
            offset = metrics.get('landing_error_in_container')
            reasons.append('not in the container' + (
                '' if offset is None else f' ({offset * 1e3:.0f} mm from its centre at the rim)'))
        elif metrics.get('t_release') is not None and metrics.get('landing_error') is None:
            reasons.append('no landing within the run')
    elif task in PLACE_TASKS:
        if metrics.get('t_grasp') is not None and metrics.get('t_release') is None:
            reasons.append('no release')
        checks = [('place_position_error', PLACE_LIMIT, 'm'),
                  ('place_speed', PLACE_SPEED_LIMIT, 'm/s'),
                  ('box_tilt_at_place', PLACE_TILT_LIMIT, 'deg')]
    for key, limit, unit in checks:
        value = metrics.get(key)
        if value is not None and value > limit:
            reasons.append(_exceeds(key, value, limit, unit))
    return '; '.join(reasons) or 'failed its success criteria'
