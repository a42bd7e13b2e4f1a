"""PyBullet backend: the arm with its gripper, the bricks, stepping, IK, contacts and camera."""
