"""The symbolic layer: forward kinematics and the closure system in CasADi SX."""
