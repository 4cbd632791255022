"""stiffcomp's science core: kinematics, joint springs, effects, identification and diagnosis.

Nothing in this package imports the service or a protocol; the service and the tools use it.
"""
