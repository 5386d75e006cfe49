"""Setup for the mr_damper_bringup ament_python package."""
import glob

from setuptools import find_packages, setup

package_name = 'mr_damper_bringup'
PACKAGE_DESCRIPTION = (
    'Bring-up of the MR damper suite: launch file, parameter YAMLs, the launcher '
    '(mr-damper-suite), the recorder (mr-damper-record, one MCAP) and the run report.'
)

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', glob.glob('launch/*.launch.py')),
        # the parameter YAMLs and the Fast DDS loopback profile (config/fastdds_loopback.xml)
        ('share/' + package_name + '/config',
         glob.glob('config/*.yaml') + glob.glob('config/*.xml')),
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
            'quarter-car-sim = mr_damper_bringup.ride_study_cli:main',
            'mr-damper-suite = mr_damper_bringup.entry_points:suite',
            'mr-damper-record = mr_damper_bringup.entry_points:record',
        ],
    },
)
