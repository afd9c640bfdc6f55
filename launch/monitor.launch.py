"""Launch the fall monitor alone, on a robot: state estimator, feature and predictor nodes.

Usage (full ROS 2 install, package built with colcon)::

    ros2 launch fall_predictor monitor.launch.py namespace:=robot1
    ros2 launch fall_predictor monitor.launch.py measurement_topic:=/robot1/estimator/measurement \
        params_file:=/path/to/my_monitor.yaml model_path:=/path/to/my_robot_model.json

By default the feature and predictor nodes run in one process on one executor (the
``fall_monitor`` executable); ``single_process:=false`` starts them as separate processes.
The state estimator runs in front of them on the robot's raw sensors (``joint_states``,
``imu/data``, the foot wrenches, ``robot_description``); ``estimator:=false`` leaves it out
for a robot that publishes ``fall_predictor/measurement`` itself. All
topics are relative, so ``namespace`` moves the whole interface (``/robot1/fall_predictor/...``);
``measurement_topic`` remaps the monitor's input. Parameters come from ``config/monitor.yaml``
(``params_file``), whose ``/**/<node>`` sections match under any namespace; ``model_path`` is
applied on top of it.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


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
        DeclareLaunchArgument('model_path', default_value='',
                              description='model file; empty = the shipped default model'),
        DeclareLaunchArgument('measurement_topic', default_value='fall_predictor/measurement',
                              description='the monitor\'s input topic (remapping)'),
        DeclareLaunchArgument('single_process', default_value='true',
                              description='true: fall_monitor (one process); false: one per node'),
        DeclareLaunchArgument('estimator', default_value='true',
                              description='true (default): the state estimator on the raw sensor '
                                          'topics; false: the robot publishes the measurement'),
    ]
    model = {'model_path': ParameterValue(LaunchConfiguration('model_path'), value_type=str)}
    remappings = [('fall_predictor/measurement', LaunchConfiguration('measurement_topic'))]

    def node(executable: str, condition, name: str | None = None, **kwargs) -> Node:
        return Node(package='fall_predictor', executable=executable, name=name,
                    namespace=namespace, parameters=[params_file, model],
                    remappings=remappings, output='screen', condition=condition, **kwargs)

    return LaunchDescription(arguments + [
        node('fall_monitor', IfCondition(single_process),
             arguments=[PythonExpression(["'--estimator' if '", estimator,
                                          "' == 'true' else ''"])]),
        # The state estimator reads no model: the params file alone.
        Node(package='fall_predictor', executable='state_estimator_node',
             name='state_estimator_node', namespace=namespace, parameters=[params_file],
             remappings=remappings, output='screen',
             condition=IfCondition(PythonExpression(["'", single_process, "' != 'true' and '",
                                                     estimator, "' == 'true'"]))),
        node('feature_node', UnlessCondition(single_process), 'feature_node'),
        node('predictor_node', UnlessCondition(single_process), 'predictor_node'),
    ])
