"""
dual_arm_bench: the performance numbers of this machine, printed (and optionally saved as JSON).

1. Per-call compute of each node's work, median and p99, timed inside a whole paper_toss
   episode of the in-process runner (the same core calls the nodes make): tracker, DS, wrench
   QP, one arm's controller, bridge step.
2. Lockstep real-time factor of the full node graph on paper_toss (separate processes, DDS).
3. Realtime mode of the full graph (FRI 500 Hz, DS 200 Hz), repeated paper_toss episodes for
   --duration wall seconds: late cycles and commands, watchdog holds, DS tick gaps, episodes,
   and the CPU share of every process.
4. dual_arm_eval throughput: trials per hour with the in-process and the graph runner.
"""

import argparse
import json
import os
from pathlib import Path
import platform
import subprocess
import sys
import tempfile
import time

from dual_arm_control.benchmarks.graph_bench import (DS_PERIOD, lockstep_real_time_factor,
                                                     realtime_run)
from dual_arm_control.inprocess import run_episode, StageTimer
from dual_arm_control.resources import config_path
from dual_arm_control.scenario import load_scenario
import numpy as np

STAGES = ('tracker', 'ds', 'qp', 'controller', 'bridge_step')
EVAL_SCENARIO = 'paper_toss_random.yaml'


def stage_timings(scenario_name='paper_toss'):
    """Return {stage: {'calls', 'median_us', 'p99_us'}} over one in-process episode."""
    timer = StageTimer()
    run_episode(load_scenario(scenario_name), timer=timer)
    timings = {}
    for stage in STAGES:
        micros = np.array(timer.samples.get(stage, [])) * 1e6
        timings[stage] = {'calls': int(micros.size),
                          'median_us': float(np.median(micros)) if micros.size else None,
                          'p99_us': float(np.percentile(micros, 99)) if micros.size else None}
    return timings


def eval_throughput(out, runner, trials, jobs):
    """Run dual_arm_eval; return {'runner', 'trials', 'jobs', 'wall', 'trials_per_hour'}."""
    command = [str(Path(sys.executable).parent / 'dual_arm_eval'),
               '--scenario', str(config_path('scenarios', EVAL_SCENARIO)),
               '--trials', str(trials), '--jobs', str(jobs), '--runner', runner,
               '--out', str(out)]
    started = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True)
    wall = time.monotonic() - started
    if result.returncode not in (0, 1):
        raise RuntimeError(f'dual_arm_eval failed ({result.returncode}): {result.stderr[-2000:]}')
    return {'runner': runner, 'trials': trials, 'jobs': jobs, 'wall': wall,
            'trials_per_hour': 3600.0 * trials / wall}


def machine_description():
    """Return what the numbers depend on: CPU model, cores, Python, OS."""
    model = 'unknown'
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return {'cpu': model, 'cores': os.cpu_count(), 'python': platform.python_version(),
            'system': platform.platform()}


def _print_timings(timings):
    print('per-call compute inside a paper_toss episode (in-process runner):')
    for stage, numbers in timings.items():
        if numbers['calls']:
            print(f'  {stage:12s} {numbers["calls"]:5d} calls  median {numbers["median_us"]:8.1f}'
                  f' us  p99 {numbers["p99_us"]:8.1f} us')


def _print_realtime(result):
    counters = result['counters']
    cycles = max(counters.get('cycles', 0), 1)
    late_commands = sum(counters.get(f'{arm}_late_commands', 0) for arm in ('left', 'right'))
    print(f'realtime, full graph, {result["episodes"]} paper_toss episodes in '
          f'{result["wall"]:.1f} s wall ({result["episodes_released"]} released the box, '
          f'{result["episodes_home"]} came home): {counters.get("late_cycles", 0)} late FRI '
          f'cycles of {cycles} ({100.0 * counters.get("late_cycles", 0) / cycles:.2f} %), '
          f'{late_commands} late commands ({50.0 * late_commands / cycles:.2f} %), watchdog '
          f'holds {counters.get("watchdog_hold_count", 0)}, FRI clock stalls (5 cycles or more) '
          f'{counters.get("cycle_stalls", 0)}, longest gap '
          f'{1e3 * counters.get("longest_cycle_gap", 0.0):.1f} ms')
    expected = result['wall'] / DS_PERIOD
    gap = result['ds_gap_p99_ms']
    print(f'  DS ticks seen {result["ds_ticks"]} (200 Hz over the wall time: {expected:.0f}), '
          f'gaps > 9 ms {result["ds_late_ticks"]} '
          f'({100.0 * result["ds_late_ticks"] / max(result["ds_ticks"], 1):.2f} %), p99 gap '
          f'{gap if gap is None else round(gap, 1)} ms')
    for name, lags in sorted(result.get('controller_lags', {}).items()):
        shares = {key: 100.0 * lags[f'{key}_behind'] / max(lags['cycles'], 1)
                  for key in ('ds_command', 'contact_wrench')}
        print(f'  {name}: DS command a tick or more old in {lags["ds_command_behind"]} of '
              f'{lags["cycles"]} cycles ({shares["ds_command"]:.0f} %, longest '
              f'{lags["ds_command_lag_max_ms"]} ms), contact wrench in '
              f'{lags["contact_wrench_behind"]} ({shares["contact_wrench"]:.0f} %, longest '
              f'{lags["contact_wrench_lag_max_ms"]} ms)')
    total = 0.0
    for label, seconds in sorted(result['cpu'].items()):
        share = 100 * seconds / result['wall']
        total += share
        print(f'  CPU {label:28s} {share:5.1f} % of one core')
    print(f'  CPU total                        {total:5.1f} % of one core')


def main(argv=None):
    """Run the benchmarks and print the numbers; return the exit code."""
    parser = argparse.ArgumentParser(prog='dual_arm_bench', description=__doc__.split('\n')[1])
    parser.add_argument('--duration', type=float, default=60.0,
                        help='realtime run length [wall s] (default 60)')
    parser.add_argument('--eval-trials', type=int, default=4,
                        help='trials per dual_arm_eval throughput run (default 4)')
    parser.add_argument('--skip-graph', action='store_true',
                        help='only the in-process numbers (no DDS processes)')
    parser.add_argument('--json', type=Path, help='also write the numbers to this JSON file')
    args = parser.parse_args(argv)
    if args.duration <= 0 or args.eval_trials < 1:
        parser.error('--duration must be > 0 and --eval-trials >= 1')
    results = {'machine': machine_description()}
    print(f'machine: {results["machine"]}')
    results['stages'] = stage_timings()
    _print_timings(results['stages'])
    with tempfile.TemporaryDirectory() as directory:
        directory = Path(directory)
        evals = [('inprocess', args.eval_trials, os.cpu_count() or 1)]
        if not args.skip_graph:
            sim, wall, stepping, code = lockstep_real_time_factor(directory / 'lockstep')
            results['lockstep'] = {'sim': sim, 'wall': wall, 'real_time_factor': sim / wall,
                                   'stepping_wall': stepping,
                                   'stepping_real_time_factor': sim / stepping,
                                   'exit_code': code}
            print(f'lockstep, full graph, paper_toss: {sim:.2f} s sim in {wall:.2f} s wall, '
                  f'real-time factor {sim / wall:.2f}; from the first FRI cycle to the last '
                  f'{stepping:.2f} s, {sim / stepping:.2f} (exit {code})')
            realtime_dir = directory / 'realtime'
            realtime_dir.mkdir()
            results['realtime'] = realtime_run(realtime_dir, args.duration)
            results['realtime']['duration'] = args.duration
            _print_realtime(results['realtime'])
            evals.append(('graph', max(1, args.eval_trials // 2), 1))
        results['eval'] = []
        for runner, trials, jobs in evals:
            numbers = eval_throughput(directory / f'eval_{runner}', runner, trials, jobs)
            results['eval'].append(numbers)
            print(f'dual_arm_eval --runner {runner} --jobs {jobs}: {trials} trials in '
                  f'{numbers["wall"]:.1f} s = {numbers["trials_per_hour"]:.0f} trials/hour')
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
