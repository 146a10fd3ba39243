"""Descriptions of closed-chain robots: URDF or MJCF trees, closures, charts, rotations."""
