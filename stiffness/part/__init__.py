"""`stiffcomp part`: a machined part as a measurement (compare, learn, diagnose) and its report."""
