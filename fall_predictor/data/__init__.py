"""The lab's data: the topic contract and the array layouts on the wire, rosbag2 (MCAP) bag
I/O, push-trajectory datasets (generation, index, derived-data cache, import of recordings) and
dataset statistics.

May import: fall_predictor.monitor, rosbags, numpy; fall_predictor.sim only lazily, inside the
functions that generate trajectories, so reading a dataset never loads the simulator.
"""
