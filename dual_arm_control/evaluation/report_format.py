"""
Formatting for docs/results.md: numbers with units, the paper's values, tables, links, notes.

Shared by the report's sections (report_sections.py); plain strings, no file access.
"""

from pathlib import Path

from dual_arm_control.evaluation.paper_results import PAPER_RESULTS, RESULTS_FILE

MISSING = '—'


def number(value, digits=3, scale=1.0, unit=''):
    """Return value * scale with `digits` decimals and the unit, or MISSING for None."""
    if value is None:
        return MISSING
    text = f'{float(value) * scale:.{digits}f}'
    if float(text) == 0.0:
        text = text.lstrip('-')
    return f'{text} {unit}'.rstrip() if unit else text


def paper(key, digits=2):
    """Return the paper's value of PAPER_RESULTS[key] with its unit and qualifier."""
    entry = PAPER_RESULTS[key]
    qualifier = entry.get('qualifier', '')
    value = f'{entry["value"]:.{digits}f}' if isinstance(entry['value'], float) \
        else str(entry['value'])
    return f'{qualifier} {value} {entry["unit"]}'.replace('  ', ' ').strip()


def table(header, rows):
    """Return a markdown table."""
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header)]
    lines += ['| ' + ' | '.join(str(cell) for cell in row) + ' |' for row in rows]
    return '\n'.join(lines)


def image_links(plots, link_root):
    """Return one Markdown image line per plot path relative to the results root."""
    return [f'![{Path(plot).name}]({link_root}/{plot})' for plot in plots]


def plot_links(results, name, link_root):
    """Return the image lines of experiment name's plots, one per line."""
    plots = [f'{name}/{plot}' for plot in results[name]['plots']]
    return '\n'.join(image_links(plots, link_root))


def not_run(name):
    """Return the note that stands in for an experiment whose results.json is missing."""
    return (f'_Not run: `{name}/{RESULTS_FILE}` is missing. Run `dual_arm_experiment {name}`._'
            '\n')


def value_range(values):
    """Return 'low .. high' with three decimals, or MISSING for None."""
    return MISSING if values is None else f'{values[0]:.3f} .. {values[1]:.3f}'


def mean_std(entry, digits=2, scale=1.0):
    """Return 'mean ± std' of a statistics entry scaled by scale, or MISSING without a mean."""
    if entry is None or entry['mean'] is None:
        return MISSING
    return f'{entry["mean"] * scale:.{digits}f} ± {entry["std"] * scale:.{digits}f}'


def statistics_table(metrics, keys, stats):
    """Return the table of a dual_arm_eval summary's metrics: one row per key it has, by stats."""
    rows = [(key, *(number(metrics[key].get(stat), 4) for stat in stats),
             metrics[key].get('count', MISSING)) for key in keys if key in metrics]
    return table(('metric', *stats, 'count'), rows)


def failure_modes(failures):
    """
    Return [(mode, count)], most frequent first: a failure's mode is its first reason.

    A reason's mode is its first two clauses (split at ': '; a refusal's which arm and how
    far are a third) without the words that hold numbers.
    """
    counts = {}
    for item in failures:
        first = str(item.get('reason', '')).split(';')[0].split(' (')[0]
        first = ': '.join(first.split(': ')[:2]).strip()
        words = first.split()
        if ' > ' in first:
            mode = f'{words[0]} over its limit'
        else:
            mode = ' '.join(word for word in words
                            if not any(character.isdigit() for character in word))
        counts[mode] = counts.get(mode, 0) + 1
    return sorted(counts.items(), key=lambda entry: (-entry[1], entry[0]))


def failure_mode_sentence(failures):
    """Return the report's sentence listing the failure modes of a summary's failures."""
    modes = failure_modes(failures)
    return ('Failure modes (first reason of each failed trial): '
            + ('none' if not modes else '; '.join(f'{mode}: {count}'
                                                  for mode, count in modes)) + '.')
