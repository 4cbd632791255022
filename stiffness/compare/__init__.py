"""`stiffcomp compare`: a model against measurements, and its report."""
