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
