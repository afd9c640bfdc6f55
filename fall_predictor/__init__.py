"""fall_predictor: learned humanoid fall prediction (core library, no ROS imports)."""

__version__ = '0.1.0'
