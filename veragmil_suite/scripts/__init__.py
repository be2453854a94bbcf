"""Console commands of veragmil_suite (see setup.py entry_points)."""
