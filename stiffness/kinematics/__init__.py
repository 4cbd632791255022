"""The robot: rigid-body helpers, the DH/URDF robot, its statics and payload identification."""
