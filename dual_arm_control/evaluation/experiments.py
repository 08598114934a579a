"""
dual_arm_experiment: regenerate the paper's experiments 1, 2, 3 and 5 and docs/results.md.

`dual_arm_experiment NAME [--out DIR]`, NAME one of fast_toss (IV-A, Figures 6-7: the node graph
via dual_arm_bringup), toss_workspace (Figure 8), place_vs_toss (IV-B, Figures 9-10),
toss_to_target (landing error over the front table), catalogue_grasps (each catalogue box
tossed and placed through the node graph), report (docs/results.md from the JSON
files) or all (the five experiments into --results, then the report into --out). Each
experiment writes OUT/results.json and its PNG plots; runs are deterministic (lockstep graph,
in-process runner, fixed seeds).
"""

import argparse
from pathlib import Path
import sys

from dual_arm_control.core.exceptions import ConfigError, DualArmControlError
from dual_arm_control.evaluation.experiment_catalogue import run_catalogue_grasps
from dual_arm_control.evaluation.experiment_place_vs_toss import REPEATS, run_place_vs_toss
from dual_arm_control.evaluation.experiment_tosses import (run_fast_toss, run_toss_to_target,
                                                           run_toss_workspace)
from dual_arm_control.evaluation.paper_results import EXPERIMENTS, RESULTS_FILE

RUNNERS = {'fast_toss': run_fast_toss, 'toss_workspace': run_toss_workspace,
           'place_vs_toss': run_place_vs_toss, 'toss_to_target': run_toss_to_target,
           'catalogue_grasps': run_catalogue_grasps}


def parse_arguments(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(
        prog='dual_arm_experiment', description=__doc__.split('\n')[1])
    parser.add_argument('name', choices=EXPERIMENTS + ('report', 'all'),
                        help='experiment to regenerate, report (docs/results.md), or all (every '
                             'experiment, then the report)')
    parser.add_argument('--out', type=Path,
                        help='output directory (default docs/results/NAME); for report and all '
                             'the markdown file (default docs/results.md)')
    parser.add_argument('--results', type=Path, default=Path('docs/results'),
                        help="report and all: directory holding the experiments' results")
    parser.add_argument('--limit', type=int,
                        help='quick check: only the first N tosses / speeds / targets '
                             '(toss_workspace also samples fewer arm configurations)')
    parser.add_argument('--repeats', type=int, default=REPEATS,
                        help='place_vs_toss only: runs per task and speed (noise seeds)')
    return parser.parse_args(argv)


def main(argv=None):
    """Run one experiment, the report, or every experiment and the report; return the code."""
    args = parse_arguments(argv)
    if args.limit is not None and args.limit < 1:
        print(f'dual_arm_experiment: --limit must be >= 1, got {args.limit}', file=sys.stderr)
        return 2
    if args.repeats < 1:
        print(f'dual_arm_experiment: --repeats must be >= 1, got {args.repeats}',
              file=sys.stderr)
        return 2
    if args.name not in ('report', 'all'):
        return run_experiment(args.name, args.out or args.results / args.name, args)
    for name in EXPERIMENTS if args.name == 'all' else ():
        code = run_experiment(name, args.results / name, args)
        if code != 0:
            return code
    from dual_arm_control.evaluation.report import write_report
    out = args.out or Path('docs/results.md')
    try:
        write_report(args.results, out)
    except (DualArmControlError, OSError) as error:
        print(f'dual_arm_experiment: report failed: {error}', file=sys.stderr)
        return 1
    print(f'dual_arm_experiment: wrote {out}')
    return 0


def run_experiment(name, out, args):
    """Run experiment name into the directory out; return the exit code."""
    kwargs = {'limit': args.limit}
    if name == 'place_vs_toss':
        kwargs['repeats'] = args.repeats
    try:
        results = RUNNERS[name](out, **kwargs)
    except ConfigError as error:
        print(f'dual_arm_experiment: {error}', file=sys.stderr)
        return 2
    except (DualArmControlError, OSError) as error:
        print(f'dual_arm_experiment: {name} failed: {error}', file=sys.stderr)
        return 1
    print(f'dual_arm_experiment: {name} done in {results["wall_time"]:.1f} s, results in '
          f'{out / RESULTS_FILE}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
