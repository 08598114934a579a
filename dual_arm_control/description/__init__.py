"""
Robot description of the cell: the arm URDFs (urdf/) and the typed cell configuration.

The URDFs are the one source of kinematics and inertias for pinocchio and MuJoCo; cell.py reads
config/cell.yaml (placement, drive armature and damping, home posture, static scene).
"""
