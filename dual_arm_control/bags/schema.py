"""
Message definitions in rosbag2's 'ros2msg' schema encoding, built from the installed .msg files.

The complete definition of a type is the text of its .msg file followed by the text of every
type it depends on, depth first, each type once, the dependencies of one type in sorted order.
Each dependency is headed by a blank line, a line of 80 '=' and 'MSG: <name>', where <name> is
the type as the parent's field names it ('std_msgs/Header'; a bare 'Type' becomes
'package/Type'). That is what rosbag2 (rosbag2_cpp LocalMessageDefinitionSource) writes, and
Foxglove resolves a field's type by exactly that name.
"""

import os
from pathlib import Path
import re
import sys

from dual_arm_control.bags import BagError

DEFINITION_SEPARATOR = '=' * 80
PRIMITIVE_TYPES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring'))
HEADER_TYPE = 'std_msgs/msg/Header'
_ARRAY_SUFFIX = re.compile(r'\[[^\]]*\]$')
_STRING_BOUND = re.compile(r'^(w?string)<=\d+$')


def type_name(msg_type):
    """Return 'package/msg/Type' for a message class, or a type name given as a string."""
    if isinstance(msg_type, str):
        return normalized_type_name(msg_type)
    return f'{msg_type.__module__.split(".")[0]}/msg/{msg_type.__name__}'


def normalized_type_name(name, package=None):
    """Return 'package/msg/Type' for 'package/msg/Type', 'package/Type' or a bare 'Type'."""
    parts = name.split('/')
    if len(parts) == 3 and parts[1] == 'msg':
        return name
    if len(parts) == 2:
        return f'{parts[0]}/msg/{parts[1]}'
    if len(parts) == 1 and package:
        return f'{package}/msg/{name}'
    raise BagError(f'cannot interpret message type name {name!r}')


def share_prefixes():
    """Return the install prefixes searched for share/<package>/msg (AMENT_PREFIX_PATH)."""
    value = os.environ.get('AMENT_PREFIX_PATH') or sys.prefix
    return [Path(prefix) for prefix in value.split(os.pathsep) if prefix]


def msg_file(name):
    """Return the path of the .msg file of 'package/msg/Type' under the first prefix having it."""
    package, _, short_name = normalized_type_name(name).split('/')
    prefixes = share_prefixes()
    for prefix in prefixes:
        path = prefix / 'share' / package / 'msg' / f'{short_name}.msg'
        if path.is_file():
            return path
    raise BagError(f'no definition of {name}: {package}/msg/{short_name}.msg is not under '
                   f'share/ of {[str(p) for p in prefixes]} (AMENT_PREFIX_PATH)')


def dependency_names(definition, package):
    """
    Return the non-primitive field types of a .msg text as written, in order.

    A bare 'Type' becomes 'package/Type'. Comments, blank lines and constants are skipped; array
    and bound suffixes are removed.
    """
    names = []
    for line in definition.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        words = line.split()
        if len(words) < 2 or '=' in words[1] or (len(words) > 2 and words[2].startswith('=')):
            continue
        base = _ARRAY_SUFFIX.sub('', words[0])
        if _STRING_BOUND.match(base) or base in PRIMITIVE_TYPES:
            continue
        names.append(base if '/' in base else f'{package}/{base}')
    return names


def first_field_type(name):
    """Return the type of the first field of a message (primitive types as written)."""
    package = normalized_type_name(name).split('/')[0]
    for line in msg_file(name).read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        words = line.split()
        if len(words) >= 2 and '=' not in line:
            base = _ARRAY_SUFFIX.sub('', words[0])
            if base in PRIMITIVE_TYPES or _STRING_BOUND.match(base) or base != words[0]:
                return words[0]
            return normalized_type_name(base, package)
    return None


def message_definition(msg_type):
    """Return the complete 'ros2msg' definition text of a message class or type name."""
    seen = set()

    def with_dependencies(name):
        text = msg_file(name).read_bytes().decode()
        sections = [text]
        package = normalized_type_name(name).split('/')[0]
        for dependency in sorted(set(dependency_names(text, package))):
            if dependency not in seen:
                seen.add(dependency)
                sections.append(f'\n{DEFINITION_SEPARATOR}\nMSG: {dependency}\n')
                sections.append(with_dependencies(dependency))
        return ''.join(sections)

    return with_dependencies(type_name(msg_type))
