"""
The package's layers: core <- runtime <- nodes, tools, evaluation, without cycles or ROS below.

The import graph is read from the source (every `import` and `from ... import` of a package
module, at any depth), so a test cannot be fooled by what happens to be imported already.
"""

import ast
import os
from pathlib import Path
import subprocess
import sys

from conftest import SOURCE_ROOT

PACKAGES = ('dual_arm_control', 'sim_bridge')
# What each layer may import from the package (its own layer included).
CORE = 'dual_arm_control.core'
CONFIGURATION = ('dual_arm_control.description', 'dual_arm_control.catalogue',
                 'dual_arm_control.resources', 'dual_arm_control.scenario')
RUNTIME = 'dual_arm_control.runtime'
ROS_FREE_LAYERS = {
    CORE: (CORE,),
    RUNTIME: (CORE, RUNTIME, *CONFIGURATION),
}


def module_name(path):
    """Return the dotted module name of a source file below SOURCE_ROOT."""
    parts = list(path.relative_to(SOURCE_ROOT).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


def package_modules():
    """Return {module name: path} of every module of the package."""
    modules = {}
    for package in PACKAGES:
        for path in sorted((SOURCE_ROOT / package).rglob('*.py')):
            modules[module_name(path)] = path
    return modules


def imported_modules(path, modules):
    """Return the package modules a source file imports (resolved to existing modules)."""
    imported = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f'{node.module}.{alias.name}' for alias in node.names]
        for name in names:
            while name and name not in modules:
                name = name.rpartition('.')[0]
            if name:
                imported.add(name)
    return imported


def import_graph():
    """Return {module: set of package modules it imports}."""
    modules = package_modules()
    return {name: imported_modules(path, modules) - {name} for name, path in modules.items()}


def in_layer(module, layer):
    """Return True if module belongs to layer (a package prefix or module name)."""
    return module == layer or module.startswith(layer + '.')


def test_no_import_cycles():
    graph = import_graph()
    state = {}
    cycles = []

    def visit(module, trail):
        state[module] = 'open'
        for target in sorted(graph[module]):
            if state.get(target) == 'open':
                cycles.append(trail[trail.index(target):] + [target])
            elif target not in state:
                visit(target, trail + [target])
        state[module] = 'done'

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert not cycles, '\n'.join(' -> '.join(cycle) for cycle in cycles)


def test_core_and_runtime_import_nothing_above_them():
    graph = import_graph()
    violations = []
    for module, imported in graph.items():
        for layer, allowed in ROS_FREE_LAYERS.items():
            if not in_layer(module, layer):
                continue
            for target in imported:
                if target.split('.')[0] == 'dual_arm_control' and target != 'dual_arm_control' \
                        and not any(in_layer(target, ok) for ok in allowed):
                    violations.append(f'{module} imports {target}')
                if target.split('.')[0] == 'sim_bridge':
                    violations.append(f'{module} imports {target}')
    assert not violations, '\n'.join(violations)


def test_the_twin_does_not_import_evaluation_or_nodes():
    graph = import_graph()
    for module in ('sim_bridge.twin', 'sim_bridge.scene'):
        assert not [target for target in graph[module]
                    if in_layer(target, 'dual_arm_control.evaluation')
                    or in_layer(target, 'dual_arm_control.nodes')], module


def test_core_and_runtime_import_with_rclpy_unavailable(tmp_path):
    """Every module of core/ and runtime/ imports in a process where rclpy cannot be found."""
    modules = [name for name in package_modules()
               if in_layer(name, CORE) or in_layer(name, RUNTIME)]
    assert len(modules) > 20
    script = tmp_path / 'import_without_ros.py'
    script.write_text(
        'import importlib, sys\n'
        'class NoRos:\n'
        '    def find_spec(self, name, path=None, target=None):\n'
        "        if name.split('.')[0] in ('rclpy', 'rosidl_runtime_py') "
        "or name.split('.')[0].endswith('_msgs'):\n"
        "            raise ImportError(f'{name} is made unimportable by the test')\n"
        'sys.meta_path.insert(0, NoRos())\n'
        'for name in sys.argv[1:]:\n'
        '    importlib.import_module(name)\n'
        "blocked = [m for m in sys.modules if m.split('.')[0] == 'rclpy']\n"
        'assert not blocked, blocked\n'
        "print('imported', len(sys.argv) - 1)\n")
    result = subprocess.run([sys.executable, str(script), *modules], capture_output=True,
                            text=True, cwd=SOURCE_ROOT, env=dict(os.environ, PYTHONPATH=str(
                                SOURCE_ROOT)))
    assert result.returncode == 0, result.stderr
    assert f'imported {len(modules)}' in result.stdout


def test_the_layer_map_covers_real_modules():
    """The layer names above exist, so a rename cannot make the checks vacuous."""
    modules = package_modules()
    for layer in (CORE, RUNTIME, *CONFIGURATION):
        assert any(in_layer(name, layer) for name in modules), layer
    assert Path(modules['dual_arm_control.runtime.fri']).is_file()
