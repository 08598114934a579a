"""
Build tf2_msgs (TFMessage only) into a venv with the rosidl generators, gcc and g++.

tf2_msgs has no pip wheel, but the rosidl generators and the C/C++ headers and libraries of its
dependencies come with the ROS wheels. This generates the C structs, the C type supports
(dispatch, Fast DDS, introspection) and the Python bindings from interfaces/tf2_msgs, compiles
them and installs them the way the ROS wheels lay a message package out: libraries in
PREFIX/lib (on the LD_LIBRARY_PATH the wheels set), the Python package in site-packages, the
interface files and the ament index entries under PREFIX/share.

Usage: python tools/build_tf2_msgs.py [--prefix PREFIX] [--build-dir DIR]
"""

import argparse
import logging
from pathlib import Path
import shutil
import subprocess
import sys
import sysconfig

PACKAGE = 'tf2_msgs'
MESSAGES = ('msg/TFMessage.msg',)
DEPENDENCIES = ('geometry_msgs', 'std_msgs', 'builtin_interfaces')
SOURCE = Path(__file__).resolve().parent.parent / 'interfaces' / PACKAGE
TYPESUPPORTS = ('rosidl_typesupport_fastrtps_c', 'rosidl_typesupport_introspection_c')


def generate(build, prefix):
    """Run the rosidl generators; return {generator: output directory}."""
    # The ROS wheels install each generator's metadata twice; rosidl_cli warns about it.
    logging.getLogger('rosidl_cli').setLevel(logging.ERROR)
    from rosidl_generator_c.cli import GenerateC
    from rosidl_generator_py.cli import GeneratePython
    from rosidl_typesupport_c.cli import GenerateCTypesupport
    from rosidl_typesupport_fastrtps_c.cli import GenerateFastRTPSCTypesupport
    from rosidl_typesupport_introspection_c.cli import GenerateIntrospectionCTypesupport
    generators = {
        'c': GenerateC, 'typesupport_c': GenerateCTypesupport,
        'fastrtps_c': GenerateFastRTPSCTypesupport,
        'introspection_c': GenerateIntrospectionCTypesupport, 'py': GeneratePython}
    interface_files = [f'{SOURCE}:{message}' for message in MESSAGES]
    outputs = {}
    for name, extension in generators.items():
        # C headers must be found as <tf2_msgs/msg/...>; Python sources form the package.
        outputs[name] = build / name / PACKAGE
        extension(name).generate(PACKAGE, interface_files, [str(prefix / 'share')],
                                 outputs[name])
    return outputs


def compile_library(target, sources, include_dirs, libraries, prefix, cxx=False):
    """Compile sources into the shared library target, linked against libraries."""
    compiler = 'g++' if cxx else 'gcc'
    command = [compiler, '-shared', '-fPIC', '-O2', '-w', '-o', str(target),
               *[str(source) for source in sources],
               *[f'-I{directory}' for directory in include_dirs],
               f'-L{prefix / "lib"}', f'-L{target.parent}', '-Wl,-rpath,$ORIGIN',
               f'-Wl,-rpath,{prefix / "lib"}',
               *[f'-l{library}' for library in libraries]]
    if cxx:
        command.insert(1, '-std=c++17')
    subprocess.run(command, check=True)
    return target


def build_libraries(outputs, build, prefix):
    """Compile the generated sources; return the paths of the libraries and modules."""
    lib = build / 'lib'
    lib.mkdir(parents=True, exist_ok=True)
    generated = ('c', 'typesupport_c', 'fastrtps_c', 'introspection_c')
    include_dirs = [build / name for name in generated] + [prefix / 'include']
    include_dirs += sorted(path for path in (prefix / 'include').iterdir() if path.is_dir())
    python_include = sysconfig.get_paths()['include']
    import numpy
    include_dirs += [python_include, numpy.get_include()]
    msg_libs = {kind: [f'{dep}__{kind}' for dep in DEPENDENCIES] for kind in (
        'rosidl_generator_c', 'rosidl_typesupport_c', 'rosidl_typesupport_fastrtps_c',
        'rosidl_typesupport_introspection_c', 'rosidl_generator_py')}
    base = ['rosidl_runtime_c', 'rcutils']

    def sources(name, pattern):
        return sorted((outputs[name]).rglob(pattern))

    generator_c = compile_library(
        lib / f'lib{PACKAGE}__rosidl_generator_c.so', sources('c', '*.c'), include_dirs,
        msg_libs['rosidl_generator_c'] + base, prefix)
    own_c = f'{PACKAGE}__rosidl_generator_c'
    libraries = [generator_c]
    libraries.append(compile_library(
        lib / f'lib{PACKAGE}__rosidl_typesupport_introspection_c.so',
        sources('introspection_c', '*.c'), include_dirs,
        [own_c, *msg_libs['rosidl_typesupport_introspection_c'],
         'rosidl_typesupport_introspection_c', *base], prefix))
    libraries.append(compile_library(
        lib / f'lib{PACKAGE}__rosidl_typesupport_fastrtps_c.so',
        sources('fastrtps_c', '*.cpp'), include_dirs,
        [own_c, *msg_libs['rosidl_typesupport_fastrtps_c'], 'rosidl_typesupport_fastrtps_c',
         'rosidl_typesupport_fastrtps_cpp', 'fastcdr', 'rmw', 'rosidl_dynamic_typesupport',
         *base], prefix, cxx=True))
    libraries.append(compile_library(
        lib / f'lib{PACKAGE}__rosidl_typesupport_c.so', sources('typesupport_c', '*.cpp'),
        include_dirs, [own_c, *msg_libs['rosidl_typesupport_c'], 'rosidl_typesupport_c',
                       *base], prefix, cxx=True))
    python_lib = compile_library(
        lib / f'lib{PACKAGE}__rosidl_generator_py.so',
        sorted((outputs['py'] / 'msg').glob('*_s.c')), include_dirs,
        [own_c, f'{PACKAGE}__rosidl_typesupport_c', *msg_libs['rosidl_generator_py'],
         *msg_libs['rosidl_generator_c'], *msg_libs['rosidl_typesupport_c'], *base],
        prefix)
    libraries.append(python_lib)
    modules = []
    for typesupport in ('rosidl_typesupport_c', *TYPESUPPORTS):
        entry = outputs['py'] / f'_{PACKAGE}_s.ep.{typesupport}.c'
        modules.append(compile_library(
            lib / f'{PACKAGE}_s__{typesupport}.so', [entry], include_dirs,
            [f'{PACKAGE}__rosidl_generator_py', f'{PACKAGE}__{typesupport}', own_c, 'rmw',
             'rosidl_dynamic_typesupport', *base], prefix))
    return libraries, modules


def install(outputs, libraries, modules, prefix):
    """Copy libraries, the Python package, interface files and ament index entries."""
    for library in libraries:
        shutil.copy2(library, prefix / 'lib' / library.name)
    site_packages = Path(sysconfig.get_paths(vars={'base': str(prefix),
                                                   'platbase': str(prefix)})['purelib'])
    package_dir = site_packages / PACKAGE
    if package_dir.exists():
        shutil.rmtree(package_dir)
    (package_dir / 'msg').mkdir(parents=True)
    (package_dir / '__init__.py').write_text('')
    for module in (outputs['py'] / 'msg').glob('*.py'):
        shutil.copy2(module, package_dir / 'msg' / module.name)
    for module in modules:
        shutil.copy2(module, package_dir / module.name)
    share = prefix / 'share' / PACKAGE
    (share / 'msg').mkdir(parents=True, exist_ok=True)
    for message in MESSAGES:
        stem = Path(message).stem
        shutil.copy2(SOURCE / message, share / 'msg' / f'{stem}.msg')
        shutil.copy2(outputs['c'] / 'tmp' / 'msg' / f'{stem}.idl', share / 'msg' / f'{stem}.idl')
        shutil.copy2(outputs['c'] / 'msg' / f'{stem}.json', share / 'msg' / f'{stem}.json')
    index = prefix / 'share' / 'ament_index' / 'resource_index'
    interfaces = [f'msg/{Path(m).stem}.{kind}' for m in MESSAGES for kind in ('idl', 'msg')]
    for resource, content in (('packages', ''), ('rosidl_interfaces', '\n'.join(interfaces)),
                              ('package_run_dependencies', ';'.join(DEPENDENCIES))):
        (index / resource).mkdir(parents=True, exist_ok=True)
        (index / resource / PACKAGE).write_text(content)


def main(argv=None):
    """Generate, compile and install tf2_msgs; exit 1 with the reason if a step fails."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--prefix', type=Path, default=Path(sys.prefix))
    parser.add_argument('--build-dir', type=Path, default=None)
    args = parser.parse_args(argv)
    prefix = args.prefix.resolve()
    build = (args.build_dir or prefix / 'build' / PACKAGE).resolve()
    if build.exists():
        shutil.rmtree(build)
    try:
        outputs = generate(build, prefix)
        libraries, modules = build_libraries(outputs, build, prefix)
    except (subprocess.CalledProcessError, OSError, RuntimeError, ImportError) as error:
        print(f'build_tf2_msgs: {error}', file=sys.stderr)
        return 1
    install(outputs, libraries, modules, prefix)
    return 0


if __name__ == '__main__':
    sys.exit(main())
