"""The robots' controllers: the ASIMO-like humanoid's model and URDF generator, closed-form leg
kinematics, the walking pattern generator, the balance controller C_bal with its reflex, the fall
controller C_fall and the one-way switch; and a team's learned walking policy run as a controller
(its network read from TorchScript into numpy, or run by onnxruntime; its deploy config; its
observation).

May import: fall_predictor.monitor (records), fall_predictor.profiles, numpy, scipy and yaml
(onnxruntime lazily, for an ONNX policy only).
"""
