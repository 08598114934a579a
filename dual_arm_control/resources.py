"""
Locate installed share files and load YAML with errors that name the file and the key.

Works from a colcon install (ament index), a pip install into a venv (share files under the
venv prefix) and a source checkout (files beside the package).
"""

import os
from pathlib import Path

from dual_arm_control.core.exceptions import ConfigError
import yaml


PACKAGE_NAME = 'dual_arm_control'
_SOURCE_ROOT = Path(__file__).resolve().parent.parent


def share_directory():
    """
    Return the package's share directory (config, urdf, launch, scenarios).

    A source checkout (editable install, tests) wins so edits to config/ take effect at once;
    otherwise the ament index, then the active venv prefix.
    """
    if (_SOURCE_ROOT / 'package.xml').is_file() and (_SOURCE_ROOT / 'config').is_dir():
        return _SOURCE_ROOT
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(PACKAGE_NAME))
    except (ImportError, LookupError, OSError, ValueError, KeyError):
        pass
    for prefix in filter(None, (os.environ.get('VIRTUAL_ENV'), os.environ.get('CONDA_PREFIX'))):
        candidate = Path(prefix) / 'share' / PACKAGE_NAME
        if (candidate / 'config').is_dir():
            return candidate
    raise ConfigError(f'cannot find the share directory of {PACKAGE_NAME}: not a source '
                      f'checkout, not in the ament index, not under $VIRTUAL_ENV/share')


def config_path(*parts):
    """Return the path of a file under the package's config directory."""
    return share_directory().joinpath('config', *parts)


def urdf_path(model_name):
    """Return the URDF of a robot model (iiwa7 or iiwa14), from the Python package itself."""
    path = Path(__file__).resolve().parent / 'description' / 'urdf' / f'{model_name}.urdf'
    if not path.is_file():
        available = sorted(p.stem for p in path.parent.glob('*.urdf'))
        raise ConfigError(f'unknown robot model {model_name!r}; available: {available}')
    return path


def load_yaml(path):
    """Load a YAML mapping with the safe loader; errors name the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as error:
        raise ConfigError(f'{path}: cannot read ({error.strerror})') from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        raise ConfigError(f'{path}: invalid YAML: {error}') from None
    if not isinstance(data, dict):
        raise ConfigError(f'{path}: expected a mapping at the top level, got '
                          f'{type(data).__name__}')
    return data


def require(mapping, key, path, kind=None, context=''):
    """Return mapping[key], raising ConfigError naming the file and the dotted key if absent."""
    dotted = f'{context}.{key}' if context else key
    if not isinstance(mapping, dict) or key not in mapping:
        raise ConfigError(f'{path}: missing key {dotted!r}')
    value = mapping[key]
    if kind is not None and not isinstance(value, kind):
        names = kind.__name__ if isinstance(kind, type) else '/'.join(k.__name__ for k in kind)
        raise ConfigError(f'{path}: key {dotted!r} must be {names}, got {value!r}')
    return value
