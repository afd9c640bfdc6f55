"""Robot profiles: one YAML file per robot (``<name>/profile.yaml``, beside its URDF), its loader
and types (:mod:`.profile`: ``load_profile``, ``RobotProfile``, ``ProfileError``, ...), its
controllers' entries (:mod:`.controller_entries`), its checks (:mod:`.checks`). Every
robot-specific fact of the package lives here.

May import: ``monitor`` (the sole geometry and sensor layout types). Loaded by the onboard
nodes too: nothing here imports the simulator or ROS. This ``__init__`` imports nothing, so the
modules of the package may import each other without an import cycle through it.
"""
