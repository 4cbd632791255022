"""Identification: least squares, what a campaign can determine, gross errors, sanity checks."""
