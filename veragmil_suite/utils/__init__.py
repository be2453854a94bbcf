"""Helpers every layer shares: asset paths, rendering set-up, MJCF text, kinematics, worker pools, log filters."""
