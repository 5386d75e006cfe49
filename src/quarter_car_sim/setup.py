"""Setup for the quarter_car_sim ament_python package."""
import glob

from setuptools import find_packages, setup

package_name = 'quarter_car_sim'
PACKAGE_DESCRIPTION = (
    'The simulator of the MR damper suite: the quarter car and the 7-DOF full car on roads '
    'with their damper plants and simulated vehicle sensors, ride and ISO 2631-1 metrics, '
    'offline optimal semi-active bounds, offline and live closed loops, hardware in the loop, '
    "the simulated cars' nodes; the control laws and the vehicle's nodes are "
    "semi_active_control's."
)

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob.glob('config/*.yaml')),
        # the vehicle's nodes moved to semi_active_control: their old names keep working for
        # one release, with a warning, where `ros2 run quarter_car_sim <name>` looks for them
        # (not as console scripts: those would take the new names' place on a pip install's
        # PATH)
        ('lib/' + package_name, sorted(glob.glob('scripts/*'))),
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
            'quarter_car_node = quarter_car_sim.nodes.entry_points:quarter_car_node',
            'full_car_node = quarter_car_sim.nodes.entry_points:full_car_node',
            'full-car-sim = quarter_car_sim.tools.full_car_sim:main',
        ],
    },
)
