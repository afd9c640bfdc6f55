"""The simulated ASIMO-like humanoid: its model (dimensions, masses, joints) and the URDF
generated from it, closed-form leg kinematics, the walking pattern generator, the balance
controller C_bal with its reflex, the fall controller C_fall and the one-way switch.

May import: fall_predictor.monitor (records), numpy and scipy.
"""
