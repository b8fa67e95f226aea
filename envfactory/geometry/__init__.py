"""The robot's geometry, built once per robot per process and shared by every env: URDF assembly,
kinematics (FK/IK), the scene's obstacles, collision shapes and their compiled kernels, the gripper
sweep, the self-collision pair list, the safety proof and the object press guard."""
