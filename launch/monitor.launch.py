"""Launch the fall monitor alone, on a robot: state estimator, feature and predictor nodes.

Usage (full ROS 2 install, package built with colcon)::

    ros2 launch fall_predictor monitor.launch.py namespace:=robot1
    ros2 launch fall_predictor monitor.launch.py input:=unitree_hg robot:=g1_12dof   # a Unitree G1
    ros2 launch fall_predictor monitor.launch.py measurement_topic:=/robot1/estimator/measurement \
        params_file:=/path/to/my_monitor.yaml model_path:=/path/to/my_robot_model.json

By default the feature and predictor nodes run in one process on one executor (the
``fall_monitor`` executable); ``single_process:=false`` starts them as separate processes.
The state estimator runs in front of them on the robot's raw sensors (``joint_states``,
``imu/data``, the foot wrenches, ``robot_description``); ``estimator:=false`` leaves it out
for a robot that publishes ``fall_predictor/measurement`` itself. ``input:=unitree_hg`` is a
Unitree humanoid on its own topic: the estimator reads ``lowstate`` (``unitree_hg/msg/LowState``)
instead of ``joint_states`` and ``imu/data``, and publishes the profile's ``robot_description``
(the robot publishes none); the profile names the motors (``g1``, or ``g1_12dof`` for the G1
under Unitree's 12-joint policy). All
topics are relative, so ``namespace`` moves the whole interface (``/robot1/fall_predictor/...``);
``measurement_topic`` remaps the monitor's input. Parameters come from ``config/monitor.yaml``
(``params_file``), whose ``/**/<node>`` sections match under any namespace. ``robot`` (a robot
profile: ``g1``, or the path to your own) and ``model_path`` are applied on top of it, each only
to the nodes that read it (:data:`SCOPED_PARAMETERS`), and only when given: an empty value
leaves the params file's. Without a ``model_path`` the monitor runs the model the robot's
profile names.
"""
import json
import os
import tempfile

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

#: Launch arguments applied as parameters, and the only nodes that get each (the nodes that
#: declare it: ROS 2 would ignore it elsewhere without a word).
SCOPED_PARAMETERS = {
    'robot': ('state_estimator_node', 'feature_node', 'predictor_node'),
    'input': ('state_estimator_node',),
    'model_path': ('feature_node', 'predictor_node'),
}


def scoped_params_file(context) -> list[str]:
    """A params file (written for this launch) with each given ``SCOPED_PARAMETERS`` argument in
    the sections of the nodes that read it; none when no such argument is given."""
    sections: dict = {}
    for argument, nodes in SCOPED_PARAMETERS.items():
        value = LaunchConfiguration(argument).perform(context)
        if value:
            for node in nodes:
                sections.setdefault(f'/**/{node}', {'ros__parameters': {}})['ros__parameters'][argument] = value
    if not sections:
        return []
    handle, path = tempfile.mkstemp(prefix='fall_predictor_monitor_', suffix='.yaml')
    with os.fdopen(handle, 'w') as out:
        json.dump(sections, out)                      # JSON is YAML
    return [path]


def generate_launch_description() -> LaunchDescription:
    params_file = LaunchConfiguration('params_file')
    namespace = LaunchConfiguration('namespace')
    single_process = LaunchConfiguration('single_process')
    estimator = LaunchConfiguration('estimator')
    arguments = [
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of the monitor (e.g. robot1)'),
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare('fall_predictor'), 'config', 'monitor.yaml']),
            description='parameters of the feature and predictor nodes (ROS 2 params file)'),
        DeclareLaunchArgument('robot', default_value='',
                              description="robot profile (e.g. g1, or a profile file's path); "
                                          "'' = the params file's"),
        DeclareLaunchArgument('model_path', default_value='',
                              description="model file; '' = the params file's, else the model "
                                          "the robot's profile names"),
        DeclareLaunchArgument('measurement_topic', default_value='fall_predictor/measurement',
                              description='the monitor\'s input topic (remapping)'),
        DeclareLaunchArgument('single_process', default_value='true',
                              description='true: fall_monitor (one process); false: one per node'),
        DeclareLaunchArgument('input', default_value='',
                              description="the robot's sensor topics: '' = the params file's "
                                          "(sensor_msgs: joint_states, imu/data, foot wrenches); "
                                          "unitree_hg: a Unitree humanoid's lowstate"),
        DeclareLaunchArgument('estimator', default_value='true',
                              description='true (default): the state estimator on the raw sensor '
                                          'topics; false: the robot publishes the measurement'),
    ]
    remappings = [('fall_predictor/measurement', LaunchConfiguration('measurement_topic'))]

    def nodes(context) -> list[Node]:
        scoped = scoped_params_file(context)

        def node(executable: str, condition, name: str | None = None, **kwargs) -> Node:
            return Node(package='fall_predictor', executable=executable, name=name,
                        namespace=namespace, parameters=[params_file, *scoped],
                        remappings=remappings, output='screen', condition=condition, **kwargs)

        return [
            node('fall_monitor', IfCondition(single_process),
                 arguments=[PythonExpression(["'--estimator' if '", estimator,
                                              "' == 'true' else ''"])]),
            node('state_estimator_node', IfCondition(PythonExpression(
                ["'", single_process, "' != 'true' and '", estimator, "' == 'true'"])),
                'state_estimator_node'),
            node('feature_node', UnlessCondition(single_process), 'feature_node'),
            node('predictor_node', UnlessCondition(single_process), 'predictor_node'),
        ]

    return LaunchDescription(arguments + [OpaqueFunction(function=nodes)])
