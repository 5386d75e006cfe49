"""Setup for the mr_damper_common ament_python package."""
from setuptools import find_packages, setup

package_name = 'mr_damper_common'

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
    description='What every node of the MR damper suite shares: node helpers, message '
                'conversions, diagnostics and health, command limits, stamp checks, stop flag.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
)
