"""The launch files and params files, checked for facts a real ``ros2 launch`` relies on.

``launch_ros`` is not installed here (no full ROS 2), so the launch files are read, not run:
each parses as Python and defines ``generate_launch_description``; every executable it names
is a console script of ``setup.py``; every ``LaunchConfiguration`` it reads is a declared launch
argument; its default params file exists in ``config/`` (installed by ``setup.py``); its
``PythonExpression`` texts are Python for every value of the switches they read; and every
parameter it sets, and every parameter of the params files, is one that the node it reaches
declares (asked of the nodes themselves, built with rclpy): ROS 2 ignores an undeclared
parameter without a word.
"""
from __future__ import annotations

import ast
import itertools
import re
from pathlib import Path

import pytest
import rclpy
from rclpy.parameter import Parameter
import yaml

REPO = Path(__file__).resolve().parents[1]
LAUNCH_FILES = ('fall_predictor.launch.py', 'monitor.launch.py')
#: Executables that run several nodes in one process (fall_monitor: the estimator with --estimator).
PROCESS_NODES = {'simulated_robot': ('simulator_node', 'controller_node'),
                 'fall_monitor': ('state_estimator_node', 'feature_node', 'predictor_node')}


def _console_scripts() -> set[str]:
    text = (REPO / 'setup.py').read_text()
    return set(re.findall(r"'(\w+) = fall_predictor\.ros\.\w+:main'", text))


@pytest.fixture(scope='module')
def declared(tmp_path_factory) -> dict[str, set[str]]:
    """Node name -> the parameters the node declares, from the node classes themselves."""
    from fall_predictor.ros.controller_node import ControllerNode
    from fall_predictor.ros.feature_node import FeatureNode
    from fall_predictor.ros.marker_node import MarkerNode
    from fall_predictor.ros.predictor_node import PredictorNode
    from fall_predictor.ros.recorder_node import RecorderNode
    from fall_predictor.ros.simulator_node import SimulatorNode
    from fall_predictor.ros.state_estimator_node import StateEstimatorNode

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=231)
    names: dict[str, set[str]] = {}
    try:
        # The recorder creates its bag directory on construction: not in the working directory.
        bags = Parameter('bag_path', value=str(tmp_path_factory.mktemp('bags')))
        for cls in (SimulatorNode, ControllerNode, StateEstimatorNode, FeatureNode, PredictorNode,
                    RecorderNode, MarkerNode):
            node = cls(context=context, **({'parameter_overrides': [bags]}
                                           if cls is RecorderNode else {}))
            names[node.get_name()] = set(node._parameters)
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    return names


class LaunchFile:
    """What a launch file states, read from its syntax tree."""

    def __init__(self, file_name: str):
        self.tree = ast.parse((REPO / 'launch' / file_name).read_text(), file_name)
        functions = {f.name: f for f in ast.walk(self.tree) if isinstance(f, ast.FunctionDef)}
        assert 'generate_launch_description' in functions
        self.calls = [c for c in ast.walk(self.tree) if isinstance(c, ast.Call)]
        #: Names bound to dict literals (parameter overrides kept in a variable).
        self.dicts = {t.id: node.value for node in ast.walk(self.tree)
                      if isinstance(node, ast.Assign) and isinstance(node.value, ast.Dict)
                      for t in node.targets if isinstance(t, ast.Name)}
        #: The local helper that wraps launch_ros' Node(...): a function with a Node call.
        self.helpers = {name: f for name, f in functions.items() if name != 'generate_launch_description'
                        and any(self._called(c) == 'Node' for c in ast.walk(f) if isinstance(c, ast.Call))}

    @staticmethod
    def _called(call: ast.Call) -> str:
        return call.func.id if isinstance(call.func, ast.Name) else getattr(call.func, 'attr', '')

    def calls_to(self, name: str) -> list[ast.Call]:
        return [c for c in self.calls if self._called(c) == name]

    def launch_arguments(self) -> dict[str, ast.expr]:
        return {c.args[0].value: next((k.value for k in c.keywords if k.arg == 'default_value'), None)
                for c in self.calls_to('DeclareLaunchArgument')}

    def configurations(self) -> set[str]:
        # LaunchConfiguration(argument) over SCOPED_PARAMETERS' keys: those, checked as such.
        return {c.args[0].value for c in self.calls_to('LaunchConfiguration')
                if isinstance(c.args[0], ast.Constant)}

    def _parameter_names(self, node: ast.AST) -> set[str]:
        """Keys of the parameter dicts under ``node`` (dict literals, or names bound to one)."""
        names = set()
        for sub in ast.walk(node):
            mapping = sub if isinstance(sub, ast.Dict) else (
                self.dicts.get(sub.id) if isinstance(sub, ast.Name) else None)
            if mapping is not None:
                names |= {k.value for k in mapping.keys if isinstance(k, ast.Constant)}
        return names

    def nodes(self) -> list[tuple[str, set[str]]]:
        """(executable, names of the parameters set on it) of every node the file starts."""
        started = []
        for call in self.calls_to('Node'):
            executable = next(k.value for k in call.keywords if k.arg == 'executable')
            if isinstance(executable, ast.Constant):
                started.append((executable.value, self._parameter_names(call)))
        for name, helper in self.helpers.items():
            inner = self._parameter_names(helper)
            for call in self.calls_to(name):
                assert isinstance(call.args[0], ast.Constant), ast.unparse(call)
                started.append((call.args[0].value, inner | self._parameter_names(call)))
        return started

    def scoped_parameters(self) -> dict[str, tuple[str, ...]]:
        """The module's ``SCOPED_PARAMETERS``: parameter -> the only nodes it is given to."""
        for node in self.tree.body:
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == 'SCOPED_PARAMETERS'
                                                    for t in node.targets):
                return ast.literal_eval(node.value)
        return {}

    def python_expressions(self) -> list[list]:
        """Each PythonExpression's parts: strings, and the names of the LaunchConfigurations."""
        expressions = []
        for call in self.calls_to('PythonExpression'):
            parts = []
            for part in call.args[0].elts:
                if isinstance(part, ast.Constant):
                    parts.append(part.value)
                else:
                    assert isinstance(part, ast.Name), ast.unparse(part)
                    parts.append(self._configuration_bound_to(part.id))
            expressions.append(parts)
        return expressions

    def _configuration_bound_to(self, variable: str) -> tuple[str]:
        for node in ast.walk(self.tree):
            if (isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == variable
                                                     for t in node.targets)
                    and isinstance(node.value, ast.Call) and self._called(node.value) == 'LaunchConfiguration'):
                return (node.value.args[0].value,)
        raise AssertionError(f'{variable} is not a LaunchConfiguration')


@pytest.mark.parametrize('file_name', LAUNCH_FILES)
def test_launch_file_names_installed_executables_and_declared_arguments(file_name):
    launch = LaunchFile(file_name)
    nodes = launch.nodes()
    assert nodes
    unknown = {executable for executable, _ in nodes} - _console_scripts()
    assert not unknown, f'not console scripts of setup.py: {sorted(unknown)}'
    arguments = launch.launch_arguments()
    undeclared = launch.configurations() - set(arguments)
    assert not undeclared, f'LaunchConfiguration without DeclareLaunchArgument: {sorted(undeclared)}'
    config = arguments['params_file']
    parts = [p.value for p in config.args[0].elts if isinstance(p, ast.Constant)]
    assert parts[0] == 'config' and (REPO / 'config' / parts[1]).is_file()
    assert "glob('config/*.yaml')" in (REPO / 'setup.py').read_text()    # installed to share/


def test_the_monitor_launch_file_expressions_are_python_for_every_switch_value():
    expressions = LaunchFile('monitor.launch.py').python_expressions()
    assert expressions
    for parts in expressions:
        switches = sorted({p[0] for p in parts if isinstance(p, tuple)})
        for values in itertools.product(('true', 'false'), repeat=len(switches)):
            chosen = dict(zip(switches, values))
            text = ''.join(chosen[p[0]] if isinstance(p, tuple) else p for p in parts)
            eval(compile(text, 'PythonExpression', 'eval'), {})   # noqa: S307 - launch evaluates it so


@pytest.mark.parametrize('file_name', LAUNCH_FILES)
def test_parameters_set_by_a_launch_file_are_declared_by_a_node_they_reach(file_name, declared):
    launch = LaunchFile(file_name)
    receivers: dict[str, set[str]] = {p: set(nodes) for p, nodes in launch.scoped_parameters().items()}
    for executable, parameters in launch.nodes():
        for parameter in parameters:
            receivers.setdefault(parameter, set()).update(PROCESS_NODES.get(executable, (executable,)))
    assert receivers
    for parameter, nodes in receivers.items():
        assert any(parameter in declared[n] for n in nodes), (parameter, sorted(nodes))


@pytest.mark.parametrize('file_name', LAUNCH_FILES)
def test_a_launch_file_sets_no_node_a_parameter_it_does_not_declare(file_name, declared):
    """ROS 2 silently ignores an undeclared parameter: each process's nodes declare what it gets."""
    for executable, parameters in LaunchFile(file_name).nodes():
        nodes = PROCESS_NODES.get(executable, (executable,))
        ignored = {p for p in parameters if not any(p in declared[n] for n in nodes)}
        assert not ignored, f'{file_name}: {executable} ignores {sorted(ignored)}'


def test_the_monitor_launch_gives_robot_model_and_input_only_to_the_nodes_that_declare_them(declared):
    """The estimator shares the fall_monitor process with the feature and predictor nodes; a
    model_path given to the whole process would reach it and be ignored: each launch argument
    goes, by node-scoped params-file sections, to exactly the nodes that declare it."""
    launch = LaunchFile('monitor.launch.py')
    scoped = launch.scoped_parameters()
    assert set(scoped) == {'robot', 'model_path', 'input'} <= set(launch.launch_arguments())
    monitor_nodes = PROCESS_NODES['fall_monitor']
    for parameter, nodes in scoped.items():
        assert set(nodes) == {n for n in monitor_nodes if parameter in declared[n]}, parameter
    assert 'model_path' not in declared['state_estimator_node']
    # Nothing is given to the whole process.
    assert all(not parameters for _, parameters in launch.nodes())


@pytest.mark.parametrize('file_name', ('fall_predictor.yaml', 'monitor.yaml'))
def test_params_file_parameters_are_declared_by_their_node(file_name, declared):
    sections = yaml.safe_load((REPO / 'config' / file_name).read_text())
    for key, section in sections.items():
        node = key.removeprefix('/**/')
        unknown = set(section['ros__parameters']) - declared[node]
        assert not unknown, f'{file_name} {key}: {sorted(unknown)} not declared by {node}'


def test_params_files_use_wildcard_sections_for_every_node():
    for name, nodes in (('fall_predictor.yaml', ('simulator_node', 'controller_node',
                                                 'state_estimator_node', 'feature_node',
                                                 'predictor_node', 'recorder_node')),
                        ('monitor.yaml', ('state_estimator_node', 'feature_node',
                                          'predictor_node'))):
        keys = re.findall(r'^(\S+):\s*$', (REPO / 'config' / name).read_text(), re.MULTILINE)
        assert keys == [f'/**/{n}' for n in nodes], name
