"""
Every third-party import of the package is declared in package.xml and in requirements.txt.

The imports are read with ast from dual_arm_control/ and sim_bridge/ (every `import` and
`from ... import`, also inside functions), leaving out the standard library
(sys.stdlib_module_names) and the package's own modules. DEPENDENCIES says, per import name,
which requirement of requirements.txt brings it on a pip install and which rosdep key package.xml
declares for a ROS install; the test also checks in the installed environment that the
requirement (or one of the distributions it pulls in) really provides the import.
"""

import ast
import functools
import importlib.metadata
import importlib.util
from pathlib import Path
import re
import sys
import xml.etree.ElementTree as ElementTree

from conftest import SOURCE_ROOT

PACKAGES = ('dual_arm_control', 'sim_bridge')
# import name: (requirement in requirements.txt, rosdep key in package.xml; None: no key exists)
DEPENDENCIES = {
    'ament_index_python': ('ros-jazzy-rclpy', 'ament_index_python'),
    'builtin_interfaces': ('ros-jazzy-rclpy', 'builtin_interfaces'),
    'rcl_interfaces': ('ros-jazzy-rclpy', 'rcl_interfaces'),
    'rclpy': ('ros-jazzy-rclpy', 'rclpy'),
    'rosgraph_msgs': ('ros-jazzy-rclpy', 'rosgraph_msgs'),
    'diagnostic_msgs': ('ros-jazzy-common-interfaces', 'diagnostic_msgs'),
    'geometry_msgs': ('ros-jazzy-common-interfaces', 'geometry_msgs'),
    'nav_msgs': ('ros-jazzy-common-interfaces', 'nav_msgs'),
    'sensor_msgs': ('ros-jazzy-common-interfaces', 'sensor_msgs'),
    'std_msgs': ('ros-jazzy-common-interfaces', 'std_msgs'),
    'std_srvs': ('ros-jazzy-common-interfaces', 'std_srvs'),
    'trajectory_msgs': ('ros-jazzy-common-interfaces', 'trajectory_msgs'),
    'visualization_msgs': ('ros-jazzy-common-interfaces', 'visualization_msgs'),
    'domain_coordinator': ('ros-jazzy-domain-coordinator', 'domain_coordinator'),
    'numpy': ('numpy', 'python3-numpy'),
    'yaml': ('PyYAML', 'python3-yaml'),
    'pinocchio': ('pin', 'pinocchio'),
    'proxsuite': ('proxsuite', 'proxsuite'),
    'mujoco': ('mujoco', 'python3-mujoco-pip'),
    # rosdep has no key for mcap alone; the pip package of this one depends on mcap.
    'mcap': ('mcap', 'mcap-ros2-support'),
    'matplotlib': ('matplotlib', 'python3-matplotlib'),
    'tqdm': ('tqdm', 'python3-tqdm'),
    'PIL': ('Pillow', 'python3-pil'),
    # rosdep has no key for imageio-ffmpeg: package.xml says so in a comment.
    'imageio_ffmpeg': ('imageio-ffmpeg', None),
}


def normalized(name):
    """Return a distribution name in its canonical form (PEP 503)."""
    return re.sub(r'[-_.]+', '-', name).lower()


def third_party_imports():
    """Return {top-level import name: [files importing it]} of the package's modules."""
    own = set(PACKAGES)
    found = {}
    for package in PACKAGES:
        for path in sorted((SOURCE_ROOT / package).rglob('*.py')):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0:
                    names = [node.module]
                else:
                    continue
                for name in names:
                    top = name.split('.')[0]
                    if top not in sys.stdlib_module_names and top not in own:
                        found.setdefault(top, []).append(str(path.relative_to(SOURCE_ROOT)))
    return found


def declared_requirements():
    """Return the normalized distribution names listed in requirements.txt."""
    names = set()
    for line in (SOURCE_ROOT / 'requirements.txt').read_text().splitlines():
        line = line.split('#')[0].strip()
        if line:
            names.add(normalized(re.match(r'[A-Za-z0-9._-]+', line).group()))
    return names


def declared_rosdep_keys():
    """Return the keys of package.xml's depend and exec_depend tags."""
    root = ElementTree.parse(SOURCE_ROOT / 'package.xml').getroot()
    return {tag.text.strip() for kind in ('depend', 'exec_depend') for tag in root.iter(kind)}


def requirement_closure(name):
    """Return the installed distributions a requirement pulls in, itself included."""
    closure, pending = set(), [normalized(name)]
    while pending:
        current = pending.pop()
        if current in closure:
            continue
        closure.add(current)
        try:
            requires = importlib.metadata.requires(current) or []
        except importlib.metadata.PackageNotFoundError:
            continue
        pending += [normalized(re.match(r'[A-Za-z0-9._-]+', r).group()) for r in requires
                    if 'extra ==' not in r]
    return closure


@functools.lru_cache(maxsize=None)
def top_level_distributions():
    """Return {top-level import name: [distribution names]} of the installed distributions."""
    return importlib.metadata.packages_distributions()


def providers(module):
    """
    Return the normalized names of the installed distributions that hold a module.

    From the distributions' top-level names, else (packages installed under a prefix, such as
    pinocchio's cmeel wheels) from the file lists that hold the module's __init__.py.
    """
    found = set(top_level_distributions().get(module, []))
    if not found:
        origin = Path(importlib.util.find_spec(module).origin).resolve()
        for distribution in importlib.metadata.distributions():
            if any(file.name == '__init__.py' and file.parent.name == module
                   and Path(distribution.locate_file(file)).resolve() == origin
                   for file in distribution.files or []):
                found.add(distribution.metadata['Name'])
    return {normalized(name) for name in found}


def test_every_third_party_import_is_declared_for_pip_and_rosdep():
    imports = third_party_imports()
    assert {'rclpy', 'numpy', 'matplotlib', 'tqdm', 'PIL'} <= set(imports), imports
    unmapped = sorted(set(imports) - set(DEPENDENCIES))
    assert not unmapped, {name: imports[name] for name in unmapped}
    stale = sorted(set(DEPENDENCIES) - set(imports))
    assert not stale, f'DEPENDENCIES lists modules the package no longer imports: {stale}'
    requirements, keys = declared_requirements(), declared_rosdep_keys()
    missing_pip = sorted(f'{module} ({pip})' for module, (pip, _) in DEPENDENCIES.items()
                         if normalized(pip) not in requirements)
    assert not missing_pip, f'not in requirements.txt: {missing_pip}'
    missing_key = sorted(f'{module} ({key})' for module, (_, key) in DEPENDENCIES.items()
                         if key is not None and key not in keys)
    assert not missing_key, f'not in package.xml: {missing_key}'
    package_xml = (SOURCE_ROOT / 'package.xml').read_text()
    for module, (pip, key) in DEPENDENCIES.items():
        if key is None:
            assert re.search(rf'<!--[^>]*{re.escape(pip)}[^>]*-->', package_xml), (
                f'package.xml must say in a comment that {pip} has no rosdep key')


def test_each_requirement_really_provides_its_import():
    wrong = {}
    for module, (pip, _) in DEPENDENCIES.items():
        held_by = providers(module)
        if not held_by & requirement_closure(pip):
            wrong[module] = f'{pip} does not bring it (it comes from {sorted(held_by)})'
    assert not wrong, wrong
