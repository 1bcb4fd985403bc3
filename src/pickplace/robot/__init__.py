"""The robot: its MJCF (``assets/``), the MuJoCo and Pinocchio models built from it, kinematics, IK, and the
gripper's geometry, commands and pad contacts."""
