"""The lab's data: rosbag2 (MCAP) bag I/O (in the message contract of
:mod:`fall_predictor.contract`), push-trajectory datasets (generation, index, derived-data cache, import of recordings) and
dataset statistics.

May import: fall_predictor.monitor, rosbags, numpy; fall_predictor.sim only lazily, inside the
functions that generate trajectories, so reading a dataset never loads the simulator.
"""
