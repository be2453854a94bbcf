"""veragmil_suite: scooping and carrying granular food with a spoon, as a robosuite task plugin.

Importing the package registers the ScoopGranular environment and the SpoonGripper with robosuite.
"""

__version__ = "0.1.0"
