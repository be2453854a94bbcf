"""Scoring agents on ScoopGranular food by food: rollouts, statistics, the paper's Tables II and III."""
