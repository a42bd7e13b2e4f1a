"""Waypoint execution (IK, interpolation over K_t servo ticks) and the classical baseline."""
