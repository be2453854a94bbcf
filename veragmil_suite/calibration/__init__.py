"""Calibration of the grains against published measurements of the real foods (python -m veragmil_suite.calibration)."""
