"""
Checks of ROS parameter files against the parameter table, before any node starts.

A parameter file (`ros__parameters` per node name, wildcards allowed) is checked for the nodes
of a graph: every key must name a parameter of a node it applies to, and every value must be
allowed there. Each problem names the file, the node key, the parameter and the reason, so the
launcher can refuse a bad file at once instead of a node dying with its reason in a log.
"""

from dual_arm_control.core.exceptions import ConfigError
from dual_arm_control.resources import load_yaml
from dual_arm_control.runtime.config_tree import config_leaves, config_with_values
from dual_arm_control.runtime.node_settings import (controller_parameter_problem, node_table,
                                                    NODE_TABLES)

WILDCARDS = ('**', '/**')
# Parameters every rclpy node declares itself.
BUILT_IN_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def key_applies(key, spec):
    """Return True if a parameter-file node key applies to a graph node (NodeSpec)."""
    key = str(key).strip('/')
    full_name = spec.full_name.strip('/')
    return key in ('**', spec.name, full_name, f'**/{spec.name}')


def _node_parameters(spec):
    """Return ({name: Setting}, {name: ConfigLeaf}, default config) of a graph node."""
    table = node_table(spec.executable)
    config = table.config() if table.config is not None else None
    leaves = {} if config is None else {leaf.name: leaf for leaf in config_leaves(config)}
    return {entry.name: entry for entry in table.settings}, leaves, config


def _value_problem(spec, name, value):
    """Return why value is not allowed for parameter name of spec; KeyError if it is unknown."""
    settings, leaves, config = _node_parameters(spec)
    if name in settings:
        return settings[name].problem(value)
    if name in leaves:
        try:
            config_with_values(config, {leaves[name].path: value})
        except ConfigError as error:
            return str(error)
        return None
    if name in BUILT_IN_PARAMETERS:
        return None
    raise KeyError(name)


def parameter_file_problems(path, graph):
    """Return the problems of a parameter file for a graph's nodes (NodeSpecs), one per line."""
    try:
        data = load_yaml(path)
    except ConfigError as error:
        return [str(error)]
    if not isinstance(data, dict):
        return [f'{path}: expected node names at the top level, got {type(data).__name__}']
    problems = []
    for key, entry in data.items():
        if not isinstance(entry, dict) or not isinstance(entry.get('ros__parameters'), dict):
            problems.append(f'{path}: {key}: expected a mapping with ros__parameters')
            continue
        nodes = [spec for spec in graph if key_applies(key, spec)]
        if not nodes:
            names = ', '.join(spec.full_name for spec in graph)
            problems.append(f'{path}: {key}: no node of the graph has this name (nodes: {names})')
            continue
        for name, value in entry['ros__parameters'].items():
            problems.extend(_parameter_problems(path, key, nodes, name, value))
        for spec in nodes:
            if spec.executable == 'passive_controller':
                reason = controller_parameter_problem(entry['ros__parameters'])
                if reason is not None:
                    problems.append(f'{path}: {key}: {reason}')
    return list(dict.fromkeys(problems))


def _parameter_problems(path, key, nodes, name, value):
    """Return the problems of one parameter of a node key (unknown everywhere, or refused)."""
    known = False
    problems = []
    for spec in nodes:
        try:
            reason = _value_problem(spec, name, value)
        except KeyError:
            continue
        known = True
        if reason is not None:
            problems.append(f'{path}: {key}: {name}: {reason}')
    if not known:
        where = ', '.join(spec.full_name for spec in nodes)
        problems.append(f'{path}: {key}: {name}: unknown parameter (not declared by {where})')
    return problems


def node_parameter_names(spec):
    """Return every parameter name a graph node declares (its settings and config leaves)."""
    settings, leaves, _ = _node_parameters(spec)
    return sorted(settings) + sorted(leaves)


def _markdown_value(value):
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_markdown_value(v) for v in value) + ']'
    if isinstance(value, float):
        return f'{value:g}'
    return f"'{value}'" if isinstance(value, str) else str(value)


def _markdown_row(name, entry):
    flags = ' (read-only)' if entry.read_only else ''
    description = entry.description.replace('|', '\\|')
    return (f'| `{name}` | {_markdown_value(entry.default)} | {entry.interval_text()} | '
            f'{entry.unit} | {description}{flags} |')


def parameter_reference():
    """Return docs/parameters.md: every node's parameters from the parameter table."""
    lines = ['# Parameters', '',
             'Generated from the parameter table (`dual_arm_control/runtime/node_settings.py` and '
             'the core config dataclasses) by `python -m dual_arm_control.parameter_files`; '
             '`test/test_parameter_table.py` checks that it is current. Every parameter is '
             'declared by its node with this description and range; a value outside the range '
             'is refused with the reason. Config-tree parameters (dotted names) change at the '
             "node's next tick.", '']
    for executable, table in NODE_TABLES.items():
        lines += [f'## {executable}', '', '| parameter | default | allowed | unit | meaning |',
                  '|---|---|---|---|---|']
        lines += [_markdown_row(entry.name, entry) for entry in table.settings]
        if table.config is not None:
            lines += [_markdown_row(leaf.name, leaf.setting)
                      for leaf in config_leaves(table.config())]
        lines.append('')
    return '\n'.join(lines)


if __name__ == '__main__':
    print(parameter_reference(), end='')
