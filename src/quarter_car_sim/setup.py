"""Setup for the quarter_car_sim ament_python package."""
import glob

from setuptools import find_packages, setup

package_name = 'quarter_car_sim'
PACKAGE_DESCRIPTION = (
    'Quarter-car simulation with semi-active MR damper control (skyhook, groundhook, '
    'hybrid, LQR reference).'
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
            'quarter_car_node = quarter_car_sim.entry_points:quarter_car_node',
            'semi_active_controller_node = '
            'quarter_car_sim.entry_points:semi_active_controller_node',
            'state_estimator_node = quarter_car_sim.entry_points:state_estimator_node',
            'full_car_node = quarter_car_sim.entry_points:full_car_node',
            'full_car_controller_node = quarter_car_sim.entry_points:full_car_controller_node',
            'full-car-sim = quarter_car_sim.full_car.cli:main',
        ],
    },
)
