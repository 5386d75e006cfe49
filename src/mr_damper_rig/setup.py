"""Setup for the mr_damper_rig ament_python package."""
import glob

from setuptools import find_packages, setup

package_name = 'mr_damper_rig'
PACKAGE_DESCRIPTION = (
    'Virtual MR damper test rig and DAQ CSV / rosbag2 replay publishing damper '
    'measurements.'
)

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob.glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='MR damper suite developers',
    maintainer_email='mr-damper-suite@example.org',
    description=PACKAGE_DESCRIPTION,
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'rig_node = mr_damper_rig.entry_points:rig_node',
            'mr-damper-rig-test = mr_damper_rig.rig_test_cli:main',
        ],
    },
)
