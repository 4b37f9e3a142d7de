from setuptools import find_packages, setup

package_name = 'stns_core'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: ['py.typed']},
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=True,
    maintainer='STNS team',
    maintainer_email='stns@example.org',
    description='The STNS learner: situations, classifier, categorical learning, STN, IPRL/PIA planners, agent, save/load.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'stns-core-bench = stns_core.bench:main'
        ],
    },
)
