"""ament_python package setup for dual_arm_control."""

from glob import glob
import os
import runpy

from setuptools import find_packages, setup

PACKAGE_NAME = 'dual_arm_control'


def console_scripts():
    """Return the console scripts from the package's executable table (one source)."""
    table = runpy.run_path(os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                        PACKAGE_NAME, 'executables.py'))
    return table['console_scripts']()


def share(subdir, pattern):
    """Return a data_files entry installing files matching pattern under share/<pkg>/subdir."""
    return (os.path.join('share', PACKAGE_NAME, subdir), sorted(glob(pattern)))


setup(
    name=PACKAGE_NAME,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={PACKAGE_NAME: ['description/urdf/*.urdf']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE_NAME]),
        ('share/' + PACKAGE_NAME, ['package.xml']),
        share('config', 'config/*.yaml'),
        share('config/scenarios', 'config/scenarios/*.yaml'),
        share('urdf', 'dual_arm_control/description/urdf/*.urdf'),
        share('launch', 'launch/*.launch.py'),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='dual_arm_control developers',
    maintainer_email='dev@dual-arm-control.example',
    description='Dual-arm grabbing with impact and tossing for two KUKA LBR iiwa arms.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={'console_scripts': console_scripts()},
)
