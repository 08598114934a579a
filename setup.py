"""ament_python package setup for dual_arm_control."""

from glob import glob
import os

from setuptools import find_packages, setup

PACKAGE_NAME = 'dual_arm_control'

CONSOLE_SCRIPTS = [
    'sim_bridge = sim_bridge.bridge_node:main',
    'gravity_comp_controller = sim_bridge.gravity_comp_controller:main',
    'dual_arm_bringup = dual_arm_control.bringup:main',
]


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
    entry_points={'console_scripts': CONSOLE_SCRIPTS},
)
