"""The STNS node suite for ROS 2 installs: ros2 launch stns_ros stns.launch.py [params_file:=FILE]

Same nodes as ``stns_bringup``: rover_sim_node (records the bag when ``record_path`` is
set), fault_injector_node and stns_agent_node, parameters from a ROS params file (default:
the workspace's config/nodes.yaml). ``stns_bringup --config FILE`` writes the complete
params file of a run into its run folder (``params.yaml``): pass it as params_file to
launch that run here. When the agent exits (``max_behaviour_steps`` reached) the launch
shuts down, which stops the simulator with SIGINT and so closes the bag; summary and
plots then come from ``stns_replay BAG --no-publish``.
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    default_params = os.path.join(os.environ.get('STNS_WS', os.getcwd()), 'config', 'nodes.yaml')
    params = LaunchConfiguration('params_file')
    agent = Node(package='stns_ros', executable='stns_agent_node', name='stns_agent',
                 parameters=[params], output='screen')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='ROS parameter file of the nodes'),
        Node(package='stns_ros', executable='rover_sim_node', name='rover_sim',
             parameters=[params], output='screen'),
        Node(package='stns_ros', executable='fault_injector_node', name='fault_injector',
             parameters=[params], output='screen'),
        agent,
        RegisterEventHandler(OnProcessExit(
            target_action=agent,
            on_exit=[EmitEvent(event=Shutdown(reason='the agent finished its behaviour steps'))])),
    ])
