"""Setup for the mr_damper_model ament_python package."""
import glob

from setuptools import find_packages, setup

package_name = 'mr_damper_model'
PACKAGE_DESCRIPTION = (
    'Magneto-rheological damper models (Kwok, current-dependent Kwok, Bingham, Bouc-'
    'Wen, Spencer), PSO identification, inverse model and the live identifier node.'
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
            'identifier_node = mr_damper_model.nodes.entry_points:identifier_node',
            'mr-damper-identify = mr_damper_model.tools.cli:main',
        ],
    },
)
