"""The simulated testbed behind one seam (``world``: the :class:`~fall_predictor.sim.world.World`
protocol and the registry of engines by name): PyBullet (``pybullet_world``, ``pybullet_state``,
``pybullet_sensors``) and MuJoCo (``mujoco_world``, ``mujoco_model``); once for every engine and
controller: the push protocol and distribution of method §3 (``pushes``), the disturbances beyond
pushes (``disturbances``: trips, slips, steps, actuator faults, long walks; their draws, onsets
and calibration: ``disturbance_runs``, ``cause_calibration``), domain randomisation
(``randomization``), the sensor model
(``sensors``) and the robot drivers' timing (``drivers``), one run from start to fallen or settled
and the shared unpushed walk it starts from (``trajectory``), a learned policy's runs
(``policy_runs``), push calibration and the robustness grid.

May import: fall_predictor.robot, fall_predictor.monitor, fall_predictor.profiles, pybullet,
mujoco, numpy.
"""
