"""The task's controller configs on robosuite's OSC_POSE and IK_POSE, and the fast arm mass-matrix path."""
