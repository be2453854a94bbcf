"""Datasets in robomimic's HDF5 schema: the recorder and writer, atomic file changes, tools, the LeRobot export."""
