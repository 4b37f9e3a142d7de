"""The STNS node suite for ROS 2 installs (ros2 launch stns_ros stns.launch.py).

Same nodes as ``stns_bringup``: rover_sim_node (records the bag when record_path is set),
stns_agent_node and fault_injector_node, parameters from a ROS params file (default: the
workspace's config/nodes.yaml). ``stns_bringup --config FILE`` writes a complete params
file for a run into its run folder (params.yaml); pass it here as params_file to launch
the same run.
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    default_params = os.path.join(os.environ.get('STNS_WS', os.getcwd()), 'config', 'nodes.yaml')
    params = LaunchConfiguration('params_file')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='ROS parameter file of the nodes'),
        Node(package='stns_ros', executable='rover_sim_node', name='rover_sim',
             parameters=[params], output='screen'),
        Node(package='stns_ros', executable='fault_injector_node', name='fault_injector',
             parameters=[params], output='screen'),
        Node(package='stns_ros', executable='stns_agent_node', name='stns_agent',
             parameters=[params], output='screen'),
    ])
