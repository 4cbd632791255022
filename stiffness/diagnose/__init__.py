"""`stiffcomp diagnose`: which effect the model misses, its plots, words and report."""
