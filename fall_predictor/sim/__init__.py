"""The simulated testbed: the PyBullet world stepped at 1 kHz with the robot's measurements,
one pushed trajectory from start to fallen or settled (and the shared unpushed walk it starts
from), and the push distribution of method §3.

May import: fall_predictor.robot, fall_predictor.monitor, pybullet, numpy.
"""
