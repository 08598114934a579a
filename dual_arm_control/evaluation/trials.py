"""
dual_arm_eval: run N trials of a scenario, drawn from its randomization block, and summarize.

Trial i is scenario.sample_trial(scenario, i): deterministic in (seed, i), so a batch is
reproducible from the scenario's seed. Each trial is written to OUT/trial_NNN/scenario.yaml (a
complete scenario file that dual_arm_bringup runs as it is) and leaves OUT/trial_NNN/metrics.json
(the per-episode contract of evaluation/episode.py). OUT/summary.json aggregates the batch and
OUT/*.png plots it. The twin runs in lockstep, except with --runner realtime: the whole graph
paced by the wall clock as the robots would pace it (one trial at a time by default).
"""

import argparse
from dataclasses import replace
import json
from pathlib import Path
import random
import sys
import time

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.description.cell import load_cell
from dual_arm_control.evaluation.grab_metrics import belt_grab_impact_speed
from dual_arm_control.evaluation.trial_plots import plot_batch
from dual_arm_control.evaluation.trial_runs import default_jobs, run_trials
from dual_arm_control.evaluation.trial_summary import failure_reason, succeeded, summarize
from dual_arm_control.scenario import load_scenario, scenario_path
from dual_arm_control.scenario_writer import scenario_document
from dual_arm_control.trial_sampling import sample_trial
from tqdm import tqdm
import yaml

RUNNERS = ('graph', 'inprocess', 'realtime')
# Highest ROS domain id Fast DDS accepts on the default port mapping.
MAX_DOMAIN_ID = 232
EXIT_USER_ERROR = 2


def trial_directory(out_dir, index):
    """Return OUT/trial_NNN, the folder of trial number index."""
    return Path(out_dir) / f'trial_{index:03d}'


def write_trial_scenario(trial, path, source, index, drawn=True):
    """Write a concrete trial scenario as a complete scenario file at path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    origin = f'trial {index} drawn from {source}' if drawn else f'{source} run as it stands'
    header = (f'# dual_arm_eval: {origin}; a complete scenario, '
              f'runnable with dual_arm_bringup --scenario <this file>.\n')
    path.write_text(header + yaml.safe_dump(scenario_document(trial), sort_keys=False,
                                            default_flow_style=None))


def parse_arguments(argv=None):
    """Parse dual_arm_eval's command line."""
    parser = argparse.ArgumentParser(
        prog='dual_arm_eval', description=__doc__.split('\n')[1],
        epilog='Exit code: 0 when summary.json is written and at least one trial produced '
               'metrics (failed trials are results), 1 when none did, 2 on a user error.')
    parser.add_argument('--scenario', required=True,
                        help='scenario YAML file (any file, or a name under config/scenarios); '
                             'its optional randomization block sets what varies between trials')
    parser.add_argument('--trials', type=int, default=1, help='number of trials N (default 1)')
    parser.add_argument('--out', type=Path, required=True,
                        help='output directory: summary.json, plots, trial_NNN/ folders')
    parser.add_argument('--runner', choices=RUNNERS, default='graph',
                        help='graph (default): each trial is a dual_arm_bringup run of the whole '
                             'node graph, as the product runs; inprocess: the same core objects '
                             'in one process per trial, ~8x faster, for large sweeps; realtime: '
                             'the graph in realtime mode (FRI cycles on the wall clock, late '
                             'commands held as the robot would), one trial at a time by default')
    parser.add_argument('--jobs', type=int,
                        help='trials run in parallel (default: one per core for inprocess, one '
                             'per two cores for graph, whose six node processes keep ~1.5 cores '
                             'busy, one for realtime, whose timing needs the whole machine); each '
                             'graph trial gets a ROS domain of its own')
    parser.add_argument('--seed', type=int,
                        help="base seed of the draws (default: the scenario file's seed)")
    parser.add_argument('--as-is', action='store_true',
                        help='run the scenario as it stands, one trial drawing nothing from it '
                             '(its own seed is the sensor-noise seed): re-runs '
                             'trial_NNN/scenario.yaml of a batch exactly, e.g. with '
                             '--keep-trajectories; needs --trials 1 and a scenario without a '
                             'randomization block')
    parser.add_argument('--keep-trajectories', action='store_true',
                        help="keep each trial's ground-truth trajectory.npz")
    parser.add_argument('--trial-timeout', type=float, default=600.0,
                        help='wall-clock limit of one graph trial [s]')
    parser.add_argument('--domain-base', type=int,
                        help='first ROS domain id of the graph trials, which use DOMAIN_BASE .. '
                             'DOMAIN_BASE + JOBS - 1 (default: random)')
    return parser.parse_args(argv)


def _check_arguments(args):
    """Return a message for the first invalid argument, or None."""
    if args.trials < 1:
        return f'--trials must be >= 1, got {args.trials}'
    if args.jobs is not None and args.jobs < 1:
        return f'--jobs must be >= 1, got {args.jobs}'
    if args.seed is not None and args.seed < 0:
        return f'--seed must be >= 0, got {args.seed}'
    if args.as_is and args.trials != 1:
        return f'--as-is runs one trial, got --trials {args.trials}'
    if args.trial_timeout <= 0.0:
        return f'--trial-timeout must be > 0 s, got {args.trial_timeout:g}'
    if args.domain_base is not None and args.domain_base < 0:
        return f'--domain-base must be >= 0, got {args.domain_base}'
    return None


def main(argv=None):
    """Run the batch; return the exit code."""
    args = parse_arguments(argv)
    problem = _check_arguments(args)
    if problem:
        print(f'dual_arm_eval: {problem}', file=sys.stderr)
        return EXIT_USER_ERROR
    cell = load_cell()
    try:
        scenario = load_scenario(args.scenario, cell=cell)
        if args.seed is not None:
            scenario = replace(scenario, seed=args.seed)
        if args.as_is and scenario.randomization is not None:
            raise ConfigError(f'{args.scenario}: --as-is needs a scenario without a '
                              'randomization block (a trial_NNN/scenario.yaml of a batch)')
        trials = ([scenario] if args.as_is else
                  [sample_trial(scenario, index, cell) for index in range(args.trials)])
    except ConfigError as error:
        print(f'dual_arm_eval: {error}', file=sys.stderr)
        return EXIT_USER_ERROR
    jobs = min(args.jobs or default_jobs(args.runner), args.trials)
    domain_base = (args.domain_base if args.domain_base is not None
                   else random.SystemRandom().randint(1, max(1, MAX_DOMAIN_ID - jobs + 1)))
    if args.runner != 'inprocess' and domain_base + jobs - 1 > MAX_DOMAIN_ID:
        print(f'dual_arm_eval: the graph trials need ROS domains {domain_base} .. '
              f'{domain_base + jobs - 1}, beyond {MAX_DOMAIN_ID}', file=sys.stderr)
        return EXIT_USER_ERROR
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        print(f'dual_arm_eval: cannot create {args.out}: {error.strerror}', file=sys.stderr)
        return EXIT_USER_ERROR
    source = scenario_path(args.scenario)
    files = []
    for index, trial in enumerate(trials):
        files.append(trial_directory(args.out, index) / 'scenario.yaml')
        write_trial_scenario(trial, files[-1], source, index, drawn=not args.as_is)
    started = time.monotonic()
    with tqdm(total=args.trials, file=sys.stderr, unit='trial',
              desc=f'{scenario.name} ({args.runner}, {jobs} jobs)') as progress:
        outcomes = run_trials(files, args.runner, jobs, args.keep_trajectories,
                              args.trial_timeout, domain_base, progress)
    wall_time = time.monotonic() - started
    aggregate = summarize([outcome.metrics for outcome in outcomes])
    failures = [{'trial': outcome.index,
                 'reason': outcome.error or failure_reason(
                     scenario.task, outcome.metrics,
                     belt_grab_impact_speed(trials[outcome.index]))}
                for outcome in outcomes if not succeeded(outcome)]
    summary = {'scenario': str(source), 'runner': args.runner, 'trials': aggregate['trials'],
               'jobs': jobs, 'seed': scenario.seed, 'success_rate': aggregate['success_rate'],
               'metrics': aggregate['metrics'], 'true_counts': aggregate['true_counts'],
               'failures': failures,
               'wall_time': wall_time, 'trials_per_hour': 3600.0 * args.trials / wall_time}
    (args.out / 'summary.json').write_text(json.dumps(summary, indent=2) + '\n')
    plot_batch(outcomes, trials, scenario, args.out, cell)
    passed = sum(succeeded(outcome) for outcome in outcomes)
    print(f'dual_arm_eval: {passed}/{args.trials} trials succeeded; '
          f'{args.out / "summary.json"}')
    return 0 if any(outcome.metrics is not None for outcome in outcomes) else 1


if __name__ == '__main__':
    sys.exit(main())
