"""
What a soak shows (soak.run_soak's records): memory, file descriptors, success, repeatability.

The targets (issue 16): the resident memory of every node grows < RSS_GROWTH_LIMIT from the end
of the warm-up to the last episode; its open file descriptors stay constant after the warm-up;
the success rate is reported per block of episodes; an episode run again with its seed gives
identical metrics; and different seeds must give different episodes (the noise is reseeded).
"""

import json

RSS_GROWTH_LIMIT = 0.05


def rss_growth(records, warmup):
    """
    Return {node: relative RSS growth} from the end of the warm-up to the last episode.

    Why from the warm-up: imports, caches and DDS discovery fill the first episodes; a leak
    shows as growth after them. The warm-up is the first `warmup` episodes (at least one).
    """
    first, last = records[max(warmup, 1) - 1], records[-1]
    return {node: (last['rss_kb'][node] - rss) / rss for node, rss in first['rss_kb'].items()}


def fd_spread(records, warmup):
    """Return {node: max - min of its open file descriptors} after the warm-up (0: constant)."""
    after = records[max(warmup, 1) - 1:]
    return {node: max(r['fds'][node] for r in after) - min(r['fds'][node] for r in after)
            for node in after[0]['fds']}


def success_per_block(records, block):
    """Return the success rate of each block of `block` episodes (the last may be shorter)."""
    return [sum(r['success'] for r in records[start:start + block])
            / len(records[start:start + block]) for start in range(0, len(records), block)]


def rerun_differences(records, reruns):
    """Return the metric names whose values differ between a re-run and its seed's episode."""
    by_seed = {record['seed']: record['metrics'] for record in records}
    differing = set()
    for rerun in reruns:
        original = by_seed[rerun['seed']]
        differing |= {key for key in set(original) | set(rerun['metrics'])
                      if json.dumps(original.get(key)) != json.dumps(rerun['metrics'].get(key))}
    return sorted(differing)


def soak_summary(records, reruns, warmup, block):
    """Return the soak's summary: the four targets above and whether all were met ('passed')."""
    if len(records) <= max(warmup, 1) or not reruns:
        return {'episodes': len(records), 'passed': False,
                'note': 'too few episodes ran for the warm-up and the re-run'}
    growth = rss_growth(records, warmup)
    spread = fd_spread(records, warmup)
    differing = rerun_differences(records, reruns)
    seeds_kept = all(record['log_seed'] == record['seed'] for record in records + reruns)
    distinct = len({json.dumps(r['metrics'], sort_keys=True) for r in records})
    summary = {
        'episodes': len(records), 'warmup': warmup,
        'rss_growth': {node: round(value, 4) for node, value in growth.items()},
        'rss_mb_last': {node: round(kb / 1024, 1) for node, kb in records[-1]['rss_kb'].items()},
        'fd_spread': spread, 'fds_last': records[-1]['fds'],
        'success_per_block': [round(rate, 3) for rate in success_per_block(records, block)],
        'rerun_seeds': [rerun['seed'] for rerun in reruns],
        'rerun_differing_metrics': differing, 'seeds_kept': seeds_kept,
        'distinct_metrics': distinct,
        'wall_time_per_episode': round(sum(r['wall_time'] for r in records) / len(records), 2)}
    summary['passed'] = (max(growth.values()) < RSS_GROWTH_LIMIT
                         and not any(spread.values()) and not differing and seeds_kept
                         and distinct > 1)
    return summary
