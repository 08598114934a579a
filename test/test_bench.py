"""dual_arm_bench runs end to end and reports every stage (numbers are printed, not judged)."""

import json
from pathlib import Path
import subprocess
import sys

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from dual_arm_control.benchmarks.bench import STAGES
from dual_arm_control.benchmarks.graph_bench import controller_lags

SCRIPTS = Path(sys.prefix) / 'bin'


def test_bench_reports_every_stage_and_the_eval_throughput(tmp_path):
    out = tmp_path / 'bench.json'
    result = subprocess.run([str(SCRIPTS / 'dual_arm_bench'), '--skip-graph', '--eval-trials',
                             '1', '--json', str(out)], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    numbers = json.loads(out.read_text())
    # A 4 s paper_toss episode: 2000 FRI cycles, one controller call per arm and cycle once the
    # DS has answered, one DS and QP call per 200 Hz tick with an object estimate.
    stages = numbers['stages']
    assert stages['bridge_step']['calls'] == 2000
    assert stages['tracker']['calls'] == 2000
    assert 700 <= stages['ds']['calls'] == stages['qp']['calls'] <= 800
    assert 2 * 1900 <= stages['controller']['calls'] <= 2 * 2000
    for stage in STAGES:
        assert 0.0 < stages[stage]['median_us'] <= stages[stage]['p99_us']
        assert stage in result.stdout
    [evaluation] = numbers['eval']
    assert evaluation['runner'] == 'inprocess' and evaluation['trials'] == 1
    assert evaluation['trials_per_hour'] > 0.0


def test_bench_refuses_bad_arguments():
    result = subprocess.run([str(SCRIPTS / 'dual_arm_bench'), '--duration', '0'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and '--duration' in result.stderr


def test_the_controller_lags_are_read_from_a_controller_status_only():
    values = {'cycles': '1988', 'ds_command_behind': '1948', 'contact_wrench_behind': '1972',
              'ds_command_lag_max_ms': '48', 'contact_wrench_lag_max_ms': '112', 'saturated': '0'}
    status = DiagnosticStatus(name='right/passive_controller', values=[
        KeyValue(key=key, value=value) for key, value in values.items()])
    assert controller_lags(status) == {
        'cycles': 1988, 'ds_command_behind': 1948, 'contact_wrench_behind': 1972,
        'ds_command_lag_max_ms': 48, 'contact_wrench_lag_max_ms': 112}
    bridge = DiagnosticStatus(name='sim_bridge', values=[KeyValue(key='cycles', value='2000')])
    assert controller_lags(bridge) is None
    status.values[0].value = 'many'
    assert controller_lags(status) is None
