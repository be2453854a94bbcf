"""ScoopGranular behind other interfaces: the Gymnasium environment veragmil/ScoopGranular-v0."""
