"""The robots' controllers behind one seam (``control``: ``JointCommand``, the ``Controller``
protocol, C_bal, a learned policy and C_fall as controllers, the one-way switch, and
``make_controller``, the one place a controller is built). C_bal itself (``controllers``: the
balance controller and its reflex) with its parts: closed-form leg kinematics from the URDF
(``legs``, ``kinematics``), the walking pattern generator (``gait``), the DCM stabilizer
(``stabilizer``), the joint servos (``actuation``). A team's learned walking policy without torch:
its deploy config (``policy_config``), its observation (``observations``), its network
(``networks``: numpy from TorchScript archives, ``torchscript``; ONNX through onnxruntime), run
as a controller (``learned_policy``).

May import: fall_predictor.monitor (records), fall_predictor.profiles, numpy, scipy and yaml
(onnxruntime lazily, for an ONNX policy only).
"""
