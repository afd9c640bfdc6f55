"""Dependencies a robot can install: package.xml names rosdep keys only, and the onboard monitor
runs without the offline tools' dependencies."""
from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Every key package.xml may name, each checked against ros/rosdistro (jazzy/distribution.yaml
#: for ROS packages, rosdep/python.yaml for the python3-* keys) when it was added. Dask
#: distributed has no key there, so it is not in package.xml (pip install distributed).
ROSDEP_KEYS = {
    # ROS 2 Jazzy packages
    'ament_cmake', 'ament_cmake_python', 'rosidl_default_generators', 'rosidl_default_runtime',
    'std_msgs', 'geometry_msgs', 'sensor_msgs', 'diagnostic_msgs', 'rosgraph_msgs', 'std_srvs',
    'rcl_interfaces', 'lifecycle_msgs', 'visualization_msgs', 'rclpy', 'ament_index_python',
    'launch', 'launch_ros', 'pinocchio',
    # rosdep/python.yaml
    'python3-numpy', 'python3-yaml', 'python3-scipy', 'python3-sklearn', 'python3-joblib',
    'python3-matplotlib', 'python3-tqdm', 'python3-pybullet-pip', 'python3-rosbags-pip',
    'python3-mujoco-pip', 'python3-onnxruntime-pip', 'python3-pytest',
}
#: Imported only by the offline tools: a robot skips them.
OFFLINE = ('pybullet', 'sklearn', 'scipy', 'matplotlib', 'distributed', 'dask', 'joblib', 'tqdm',
           'mujoco', 'onnxruntime')
OFFLINE_KEYS = {'python3-pybullet-pip', 'python3-scipy', 'python3-sklearn', 'python3-joblib',
                'python3-matplotlib', 'python3-tqdm', 'python3-mujoco-pip', 'python3-onnxruntime-pip'}


def _dependencies() -> list[ET.Element]:
    root = ET.parse(ROOT / 'package.xml').getroot()
    return [e for e in root if e.tag.endswith('depend')]


def test_package_xml_names_only_rosdep_keys():
    names = {e.text for e in _dependencies()}
    assert names <= ROSDEP_KEYS, sorted(names - ROSDEP_KEYS)
    assert 'python3-distributed' not in names


def test_the_offline_tools_dependencies_are_conditional_and_only_they():
    condition = '$FALL_PREDICTOR_OFFLINE_TOOLS != false'
    conditional = {e.text for e in _dependencies() if e.get('condition')}
    assert conditional == OFFLINE_KEYS
    assert {e.get('condition') for e in _dependencies() if e.get('condition')} == {condition}


_BLOCKED_IMPORT = '''
import importlib.abc, sys
class Blocked(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split('.')[0] in {blocked!r}:
            raise ImportError(name + ' is not installed on this robot')
sys.meta_path.insert(0, Blocked())
import fall_predictor.ros.fall_monitor
import fall_predictor.ros.state_estimator_node
import fall_predictor.ros.recorder_node
import fall_predictor.monitor.chain
print('ok')
'''


def test_the_onboard_monitor_runs_without_the_offline_tools():
    """Every module the monitor's processes import loads with pybullet, scikit-learn, SciPy,
    matplotlib, Dask, joblib and tqdm missing."""
    result = subprocess.run([sys.executable, '-c', _BLOCKED_IMPORT.format(blocked=OFFLINE)],
                            capture_output=True, text=True, timeout=120, env=dict(os.environ))
    assert result.returncode == 0 and result.stdout.strip() == 'ok', result.stderr


def test_setup_py_installs_the_monitor_and_the_offline_tools_as_an_extra():
    text = (ROOT / 'setup.py').read_text()
    core = text[text.index('install_requires=['):text.index('],', text.index('install_requires=['))]
    for module in ('pybullet', 'scikit-learn', 'scipy', 'matplotlib', 'distributed', 'joblib', 'tqdm'):
        assert module not in core, module
    assert "'offline':" in text and "'cluster':" in text
    assert '-e .[offline,cluster,test]' in (ROOT / 'requirements.txt').read_text()
