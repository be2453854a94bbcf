"""The robomimic bridge: robomimic 0.3.0 on robosuite 1.5, observations, observation sets, our algorithms."""
