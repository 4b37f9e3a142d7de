from setuptools import find_packages, setup

package_name = 'stns_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', ['launch/stns.launch.py']),
    ],
    package_data={package_name: ['py.typed']},
    install_requires=['setuptools'],
    extras_require={'test': ['pytest']},
    zip_safe=False,
    maintainer='STNS team',
    maintainer_email='stns@example.org',
    description='ROS 2 nodes over stns_core and rover_sim: simulator, agent, fault injector, MCAP recording, replay, bring-up.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'rover_sim_node = stns_ros.sim_node:main',
            'stns_agent_node = stns_ros.agent_node:main',
            'fault_injector_node = stns_ros.fault_injector_node:main',
            'stns_recorder = stns_ros.recorder_node:main',
            'stns_replay = stns_ros.replay:main',
            'stns_bringup = stns_ros.bringup:main',
        ],
    },
)
