"""The study: record -> train -> evaluate over operators, algorithms and seeds (quickstart, veragmil-study)."""
