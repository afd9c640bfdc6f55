from glob import glob

from setuptools import find_packages, setup

package_name = 'fall_predictor'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['profiles/*/*.yaml', 'profiles/*/*.urdf', 'profiles/*/*.xml',
                                 'profiles/*/LICENSE*', 'profiles/*/meshes/*',
                                 'profiles/*/controllers/*/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.py')),
        ('share/' + package_name + '/models', glob('models/*')),
        ('share/' + package_name + '/examples', glob('examples/*.py')),
    ],
    python_requires='>=3.10',
    # What the onboard monitor needs (a robot installs only this, see package.xml); the offline
    # tools (simulation, learning, plots, the Dask cluster) are the extras.
    install_requires=[
        'setuptools',
        'numpy>=1.24',
        'rosbags>=0.10',
        'pyyaml>=6',
        # Pinocchio (the state estimator's rigid-body dynamics); imported as `pinocchio`.
        'pin>=3.0',
    ],
    extras_require={
        # example-robot-data: the G1's meshes for the simulator (the monitor needs none);
        # mujoco: the second simulator; onnxruntime: learned policies given as ONNX (a
        # TorchScript policy runs in numpy, robot/networks.py). Neither has a rosdep key: on a
        # ROS install, pip install them (README).
        'offline': ['pybullet>=3.2.5', 'scipy>=1.10', 'scikit-learn>=1.3', 'joblib>=1.3',
                    'matplotlib>=3.7', 'tqdm>=4.60', 'example-robot-data>=4.1',
                    'mujoco>=3.2', 'onnxruntime>=1.17'],
        'cluster': ['distributed>=2023.1'],
        'test': ['pytest>=7', 'pytest-xdist>=3'],
    },
    zip_safe=True,
    maintainer='fall_predictor developers',
    maintainer_email='dev@fall-predictor.invalid',
    description='Learned humanoid fall prediction with ROS 2 nodes and offline tools.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'fall-predictor = fall_predictor.cli:main',
            'simulator_node = fall_predictor.ros.simulator_node:main',
            'controller_node = fall_predictor.ros.controller_node:main',
            'feature_node = fall_predictor.ros.feature_node:main',
            'predictor_node = fall_predictor.ros.predictor_node:main',
            'recorder_node = fall_predictor.ros.recorder_node:main',
            'fall_monitor = fall_predictor.ros.fall_monitor:main',
            'simulated_robot = fall_predictor.ros.simulated_robot:main',
            'state_estimator_node = fall_predictor.ros.state_estimator_node:main',
            'monitor_markers = fall_predictor.ros.marker_node:main',
        ],
    },
)
