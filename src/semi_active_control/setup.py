"""Setup for the semi_active_control ament_python package."""
import glob

from setuptools import find_packages, setup

package_name = 'semi_active_control'
PACKAGE_DESCRIPTION = (
    'The vehicle side of the MR damper suite: what runs on a car (state and identified-set '
    'types, control laws, supervision, state estimation, the vehicle nodes); never imports the '
    'simulator or the fitting stack.'
)

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/models', glob.glob('config/models/*.json')),
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
            'semi_active_controller_node = '
            'semi_active_control.nodes.entry_points:semi_active_controller_node',
            'state_estimator_node = semi_active_control.nodes.entry_points:state_estimator_node',
            'vehicle_estimator_node = '
            'semi_active_control.nodes.entry_points:vehicle_estimator_node',
            'vehicle_controller_node = '
            'semi_active_control.nodes.entry_points:vehicle_controller_node',
            'lifecycle_manager = semi_active_control.nodes.entry_points:lifecycle_manager',
        ],
    },
)
