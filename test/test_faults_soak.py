"""
The soak of dual_arm_faults: consecutive episodes in one running lockstep graph, one seed each.

A short soak runs in the suite: SOAK_EPISODES episodes of the hold scenario cut at
SOAK_DURATION, the start of the reach (about a minute on 2 cores; whole grasps, 2 s each, take
about 5 s of wall time per episode, so 50 of them would not fit in 3 minutes, and an episode cut
at 0.5 s does not meet its task: the success rate is 0 in every block). The 1000-episode soak
runs in the campaign (`dual_arm_faults --soak 1000`). The summary's judgement is checked on
made-up records too.
"""

from dual_arm_control.tools.faults.soak import run_soak, SoakPlan
from dual_arm_control.tools.faults.soak_report import soak_summary
import pytest

SOAK_EPISODES = 50
SOAK_DURATION = 0.5
NODES = {'sim_bridge', 'object_tracker', 'ds_motion_generator', 'wrench_qp',
         'left_passive_controller', 'right_passive_controller', 'cell_state_publisher'}


def record(episode, seed, rss=100_000, fds=40, success=True, landing=0.01):
    return {'episode': episode, 'seed': seed, 'log_seed': seed, 'success': success,
            'metrics': {'success': success, 'landing_error': landing},
            'rss_kb': {'node': rss}, 'fds': {'node': fds}, 'wall_time': 1.0}


def test_the_soak_summary_judges_memory_descriptors_and_the_rerun():
    records = [record(i, 10 + i, rss=90_000 + 1000 * min(i, 3), landing=0.01 + i * 1e-3)
               for i in range(20)]
    summary = soak_summary(records, [record(20, 10, landing=0.01)], warmup=4, block=10)
    assert summary['passed'] and summary['rss_growth'] == {'node': 0.0}
    assert summary['success_per_block'] == [1.0, 1.0] and summary['distinct_metrics'] == 20
    leaking = [dict(r, rss_kb={'node': 100_000 + 400 * i}) for i, r in enumerate(records)]
    summary = soak_summary(leaking, [record(20, 10, landing=0.01)], warmup=4, block=10)
    assert not summary['passed'] and summary['rss_growth']['node'] > 0.05
    opening = [dict(r, fds={'node': 40 + (i == 15)}) for i, r in enumerate(records)]
    summary = soak_summary(opening, [record(20, 10, landing=0.01)], warmup=4, block=10)
    assert not summary['passed'] and summary['fd_spread'] == {'node': 1}
    summary = soak_summary(records, [record(20, 10, landing=0.0100001)], warmup=4, block=10)
    assert not summary['passed'] and summary['rerun_differing_metrics'] == ['landing_error']
    failing = [dict(r, success=r['episode'] % 2 == 0) for r in records[:15]]
    assert soak_summary(failing, [record(20, 10, landing=0.01)], 4, 10)[
        'success_per_block'] == [0.5, 0.6]


@pytest.mark.slow
def test_a_soak_of_consecutive_episodes_in_one_graph(tmp_path, ros_domain):
    plan = SoakPlan('hold', SOAK_EPISODES, SOAK_DURATION, seed=5000, warmup=5, block=10)
    summary = run_soak(plan, tmp_path / 'soak', int(ros_domain))
    print(summary)
    assert summary['episodes'] == SOAK_EPISODES and not summary['node_exits']
    assert set(summary['rss_growth']) >= NODES
    assert max(summary['rss_growth'].values()) < 0.05
    assert not any(summary['fd_spread'].values())
    assert summary['seeds_kept'] and summary['rerun_differing_metrics'] == []
    assert summary['distinct_metrics'] > 1, 'different seeds gave the same episode'
    assert len(summary['success_per_block']) == SOAK_EPISODES // 10
    assert summary['passed']
