"""The launch files, run against a minimal stand-in of the ``launch``/``launch_ros`` API.

The ``launch`` packages are not installed here (no full ROS 2), so each launch file's
``generate_launch_description()`` runs with small recording stand-ins of the classes it uses.
The checks are what a real ``ros2 launch`` would rely on: every node is a console script of
the package, its params file exists in ``config/``, the namespace argument reaches every node,
and the monitor launch starts either ``fall_monitor`` or the two nodes, never both.
"""
from __future__ import annotations

import importlib.util
import re
import sys
import types
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


class Recorded:
    """A stand-in object that remembers how it was built."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class LaunchConfiguration(Recorded):
    @property
    def name(self):
        return self.args[0]


class Condition(Recorded):
    pass


class PythonExpression(Recorded):
    def evaluate(self, values: dict[str, str]) -> object:
        """The expression with the launch arguments substituted, evaluated as launch would."""
        text = ''.join(values[part.name] if isinstance(part, LaunchConfiguration) else part
                       for part in self.args[0])
        return eval(text)  # noqa: S307 - the launch file's own expression


class IfCondition(Condition):
    negate = False


class UnlessCondition(Condition):
    negate = True


def _stand_in_modules(monkeypatch: pytest.MonkeyPatch) -> None:
    names = {
        'launch': {'LaunchDescription': Recorded},
        'launch.actions': {'DeclareLaunchArgument': Recorded},
        'launch.conditions': {'IfCondition': IfCondition, 'UnlessCondition': UnlessCondition},
        'launch.substitutions': {'LaunchConfiguration': LaunchConfiguration,
                                 'PathJoinSubstitution': Recorded,
                                 'PythonExpression': PythonExpression},
        'launch_ros': {},
        'launch_ros.actions': {'Node': Recorded},
        'launch_ros.parameter_descriptions': {'ParameterValue': Recorded},
        'launch_ros.substitutions': {'FindPackageShare': Recorded},
    }
    for name, attributes in names.items():
        module = types.ModuleType(name)
        module.__dict__.update(attributes)
        monkeypatch.setitem(sys.modules, name, module)


def _description(monkeypatch: pytest.MonkeyPatch, file_name: str):
    _stand_in_modules(monkeypatch)
    spec = importlib.util.spec_from_file_location(file_name[:-3].replace('.', '_'),
                                                  REPO / 'launch' / file_name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    entities = module.generate_launch_description().args[0]
    arguments = {e.args[0]: e.kwargs.get('default_value') for e in entities if not e.kwargs.get('package')}
    nodes = [e for e in entities if e.kwargs.get('package') == 'fall_predictor']
    return arguments, nodes


def _console_scripts() -> set[str]:
    text = (REPO / 'setup.py').read_text()
    return set(re.findall(r"'(\w+) = fall_predictor\.ros\.\w+:main'", text))


def _params_file(arguments) -> str:
    default = arguments['params_file']
    parts = default.args[0]
    assert parts[1] == 'config'
    assert (REPO / 'config' / parts[2]).is_file()
    return parts[2]


def test_simulation_launch_file(monkeypatch):
    arguments, nodes = _description(monkeypatch, 'fall_predictor.launch.py')
    assert _params_file(arguments) == 'fall_predictor.yaml'
    assert arguments['namespace'] == ''
    assert arguments['composed_robot'] == 'false'
    executables = [n.kwargs['executable'] for n in nodes]
    assert executables == ['simulated_robot', 'simulator_node', 'state_estimator_node',
                           'controller_node', 'feature_node', 'predictor_node', 'recorder_node']
    assert set(executables) <= _console_scripts()
    for n in nodes:
        assert n.kwargs['namespace'].name == 'namespace'
        # Single-node processes are named after their executable; simulated_robot's two
        # nodes keep their own names (no renaming).
        assert n.kwargs['name'] == (None if n.kwargs['executable'] == 'simulated_robot'
                                    else n.kwargs['executable'])
    # composed_robot switches between simulated_robot and the two separate processes.
    for composed in ('true', 'false'):
        started = [n.kwargs['executable'] for n in nodes
                   if 'condition' not in n.kwargs
                   or n.kwargs['condition'].args[0].name != 'composed_robot'
                   or (composed == 'true') != n.kwargs['condition'].negate]
        robot = (['simulated_robot'] if composed == 'true'
                 else ['simulator_node', 'controller_node'])
        assert [e for e in started if e in ('simulated_robot', 'simulator_node',
                                           'controller_node')] == robot, composed
    by_executable = {n.kwargs['executable']: n for n in nodes}
    assert by_executable['simulated_robot'].kwargs['parameters'][1] is \
        by_executable['simulator_node'].kwargs['parameters'][1]    # the same overrides
    recorder, estimator = by_executable['recorder_node'], by_executable['state_estimator_node']
    assert isinstance(recorder.kwargs['condition'], IfCondition)
    assert recorder.kwargs['condition'].args[0].name == 'record'
    assert estimator.kwargs['condition'].args[0].name == 'sensors'


def test_monitor_launch_file(monkeypatch):
    arguments, nodes = _description(monkeypatch, 'monitor.launch.py')
    assert _params_file(arguments) == 'monitor.yaml'
    assert set(arguments) >= {'namespace', 'model_path', 'measurement_topic', 'single_process',
                              'estimator'}
    executables = [n.kwargs['executable'] for n in nodes]
    assert executables == ['fall_monitor', 'state_estimator_node', 'feature_node',
                           'predictor_node']
    assert set(executables) <= _console_scripts()
    # Which nodes start, for each combination of the two switches: fall_monitor (with or
    # without --estimator) in one process, or each node in its own; never both.
    for single in ('true', 'false'):
        for estimator in ('true', 'false'):
            values = {'single_process': single, 'estimator': estimator}
            started = []
            for n in nodes:
                condition = n.kwargs['condition']
                switch = condition.args[0]
                on = (switch.evaluate(values) if isinstance(switch, PythonExpression)
                      else values[switch.name] == 'true')
                if on != condition.negate:
                    extra = [a.evaluate(values) for a in n.kwargs.get('arguments', [])]
                    started.append(' '.join([n.kwargs['executable'], *filter(None, extra)]))
            expected = ({('true', 'true'): ['fall_monitor --estimator'],
                         ('true', 'false'): ['fall_monitor'],
                         ('false', 'true'): ['state_estimator_node', 'feature_node',
                                             'predictor_node'],
                         ('false', 'false'): ['feature_node', 'predictor_node']})[single, estimator]
            assert started == expected, values
    for n in nodes:
        assert n.kwargs['namespace'].name == 'namespace'
        (source, target), = n.kwargs['remappings']
        assert source == 'fall_predictor/measurement' and target.name == 'measurement_topic'
    # The one-process executable keeps its nodes' own names (no renaming).
    assert nodes[0].kwargs['name'] is None


def test_params_files_use_wildcard_sections_for_every_node():
    for name, nodes in (('fall_predictor.yaml', ('simulator_node', 'controller_node',
                                                 'state_estimator_node', 'feature_node',
                                                 'predictor_node', 'recorder_node')),
                        ('monitor.yaml', ('state_estimator_node', 'feature_node',
                                          'predictor_node'))):
        keys = re.findall(r'^(\S+):\s*$', (REPO / 'config' / name).read_text(), re.MULTILINE)
        assert keys == [f'/**/{n}' for n in nodes], name
