"""Launch the onboard fall monitor: simulator, state estimator, controller, feature and
predictor nodes, and optionally the recorder.

Usage (full ROS 2 install, package built with colcon)::

    ros2 launch fall_predictor fall_predictor.launch.py
    ros2 launch fall_predictor fall_predictor.launch.py real_time_factor:=0.0 record:=true \
        bag_path:=fall_bags model_path:=/path/to/model.json
    ros2 launch fall_predictor fall_predictor.launch.py sensors:=false  # exact state, no estimator
    ros2 launch fall_predictor fall_predictor.launch.py composed_robot:=true  # simulated_robot
    ros2 launch fall_predictor fall_predictor.launch.py controller:=c_bal simulator:=mujoco
    ros2 launch fall_predictor fall_predictor.launch.py robot:=g1_12dof  # Unitree's policy, MuJoCo

Parameters come from ``config/fall_predictor.yaml`` (``params_file``); the launch arguments
``robot``, ``real_time_factor``, ``model_path``, ``bag_path``, ``controller`` and ``simulator``
are applied on top of it, so they win over the file's values (``robot`` goes to every node that
reads it, ``model_path`` '' is the model the robot profile names; ``controller`` and
``simulator`` go to both the
simulator and the controller node; '' = the robot profile's; a learned policy needs
``sensors:=true``, the default). Each node is a console script of the package (setup.py);
``composed_robot:=true`` runs the simulator and the controller as ``simulated_robot`` (one
process, the lock-step loop closed in process, about twice as fast). All topics are
relative: ``namespace:=robot1`` runs the whole simulated system under ``/robot1``. For the
monitor alone (a real robot) use ``monitor.launch.py``.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    params_file = LaunchConfiguration('params_file')
    arguments = [
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare('fall_predictor'), 'config', 'fall_predictor.yaml']),
            description='parameters of all nodes (ROS 2 params file)'),
        DeclareLaunchArgument('robot', default_value='asimo_like',
                              description='robot profile of every node (a shipped name: '
                                          'asimo_like, g1, g1_12dof; or a profile file)'),
        DeclareLaunchArgument('model_path', default_value='',
                              description="model file; '' = the model the robot profile names"),
        DeclareLaunchArgument('real_time_factor', default_value='1.0',
                              description='simulated seconds per wall second; 0.0 = fast'),
        DeclareLaunchArgument('record', default_value='false',
                              description='also run the recorder node'),
        DeclareLaunchArgument('bag_path', default_value='',
                              description='recorder output directory (one bag per run)'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of every node and topic (e.g. robot1)'),
        DeclareLaunchArgument('sensors', default_value='true',
                              description='true (default): the simulator publishes robot sensor '
                                          'topics and state_estimator_node makes the measurement, '
                                          'as on a robot (the shipped model is trained on this '
                                          'estimated state); false: the exact simulated state'),
        DeclareLaunchArgument('controller', default_value='',
                              description="walking controller: 'c_bal' or a learned policy the "
                                          "robot profile names; '' = the profile's default"),
        DeclareLaunchArgument('simulator', default_value='',
                              description="simulator: 'pybullet' or 'mujoco'; '' = the robot "
                                          "profile's"),
        DeclareLaunchArgument('composed_robot', default_value='false',
                              description='true: simulator and controller nodes in one process '
                                          '(simulated_robot); false: one process each'),
    ]
    composed = LaunchConfiguration('composed_robot')
    # Who walks the robot and where: the same for the simulator and the controller node.
    robot = {'robot': ParameterValue(LaunchConfiguration('robot'), value_type=str)}
    walking = {'controller': ParameterValue(LaunchConfiguration('controller'), value_type=str),
               'simulator': ParameterValue(LaunchConfiguration('simulator'), value_type=str),
               **robot}
    simulator_overrides = {
        'real_time_factor': ParameterValue(LaunchConfiguration('real_time_factor'),
                                           value_type=float),
        'publish_sensors': ParameterValue(LaunchConfiguration('sensors'), value_type=bool),
        **walking}

    def node(executable: str, overrides: dict | None = None, name: str | None = '', **kwargs
             ) -> Node:
        # name '' = the executable's; None for a process of several nodes (each keeps its own).
        return Node(package='fall_predictor', executable=executable,
                    name=executable if name == '' else name,
                    namespace=LaunchConfiguration('namespace'),
                    parameters=[params_file, overrides or {}], output='screen', **kwargs)

    return LaunchDescription(arguments + [
        node('simulated_robot', simulator_overrides, None, condition=IfCondition(composed)),
        node('simulator_node', simulator_overrides, condition=UnlessCondition(composed)),
        node('state_estimator_node', robot, condition=IfCondition(LaunchConfiguration('sensors'))),
        # The simulated robot's own controller reads the simulator's exact state beside its sensors.
        node('controller_node', {'ground_truth': ParameterValue(LaunchConfiguration('sensors'),
                                                                value_type=bool), **walking},
             condition=UnlessCondition(composed)),
        # Both read the model: the feature node for the feature settings it was trained with.
        node('feature_node', {'model_path': ParameterValue(
            LaunchConfiguration('model_path'), value_type=str), **robot}),
        node('predictor_node', {'model_path': ParameterValue(
            LaunchConfiguration('model_path'), value_type=str), **robot}),
        node('recorder_node', {'bag_path': ParameterValue(
            LaunchConfiguration('bag_path'), value_type=str)},
            condition=IfCondition(LaunchConfiguration('record'))),
    ])
