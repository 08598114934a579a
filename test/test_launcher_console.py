"""
What dual_arm_bringup tells its user on the console: exit codes, and each phase as it happens.

The run test starts a shipped scenario by its name (`--scenario paper_toss`), shortened to 2.1 s
of sim time (past the release at 2.0 s, before the box lands), and reads the launcher's output
line by line as it comes.
"""

from pathlib import Path
import re
import signal
import subprocess
import sys
import threading
import time

BRINGUP = Path(sys.executable).parent / 'dual_arm_bringup'
RUN_TIMEOUT = 240.0
PHASE_LINE = re.compile(r'^  phase at (\d+\.\d+) s: (\w+)(?: \[([^]]*)\])?: (.+)$')
# Wall time between the first phase line and the end of the run: the echo is live, not a
# replay of the log at the end (2 s of sim time take well over 5 s of wall time in lockstep).
LIVE_MARGIN = 3.0


def test_help_documents_the_exit_codes():
    result = subprocess.run([str(BRINGUP), '--help'], capture_output=True, text=True,
                            timeout=30)
    text = ' '.join(result.stdout.split())
    assert result.returncode == 0
    for meaning in ('0 success', '1 task failed', '2 bad input', '3 a node died or timed out'):
        assert meaning in text, text


def test_a_shipped_scenario_runs_by_name_and_each_phase_is_echoed_as_it_happens(tmp_path):
    params = tmp_path / 'short.yaml'
    params.write_text('sim_bridge:\n  ros__parameters:\n    duration: 2.1\n')
    out = tmp_path / 'run'
    process = subprocess.Popen(
        [str(BRINGUP), '--scenario', 'paper_toss', '--params', str(params), '--out', str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(
        (time.monotonic(), line.rstrip('\n')) for line in process.stdout), daemon=True)
    reader.start()
    try:
        code = process.wait(timeout=RUN_TIMEOUT)
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            process.wait(timeout=10)
    reader.join(timeout=5)
    ended = time.monotonic()
    text = '\n'.join(line for _, line in lines)
    print(text)
    assert code == 1, text
    assert 'did not meet its task criteria' in text, 'a 2.1 s run ends before the box lands'
    assert (out / 'metrics.json').is_file()
    phases = [(arrival, PHASE_LINE.match(line)) for arrival, line in lines
              if PHASE_LINE.match(line)]
    names = [match.group(2) for _, match in phases]
    assert names[:4] == ['reach', 'contact', 'manipulate', 'release'], text
    times = [float(match.group(1)) for _, match in phases]
    assert times == sorted(times) and 0.0 < times[0] < times[-1] <= 2.1
    events = {match.group(2): (match.group(3) or '').split(', ') for _, match in phases}
    # The pad that touches second completes the grasp and the change to contact; the first
    # touch, a tick or two earlier, is an event of the reach and changes no phase.
    assert {'contact_left', 'contact_right'} & set(events['contact'])
    assert 'released' in events['release']
    assert all(match.group(4) for _, match in phases), 'each change says why'
    assert ended - phases[0][0] > LIVE_MARGIN, 'the first phase came only at the end'
