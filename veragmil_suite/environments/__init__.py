from veragmil_suite.environments.scoop import ScoopGranular

__all__ = ["ScoopGranular"]
