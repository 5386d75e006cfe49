"""Setup for the mr_damper_gym ament_python package."""
from setuptools import find_packages, setup

package_name = 'mr_damper_gym'
PACKAGE_DESCRIPTION = (
    'Gymnasium environments for learning semi-active suspension control on the suite\'s '
    'simulator (MR damper plants, vehicle sensors, ISO 2631-1 reward, the offline bound).'
)

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='MR damper suite developers',
    maintainer_email='mr-damper-suite@example.org',
    description=PACKAGE_DESCRIPTION,
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [],
    },
)
