"""The stiffness model: its effects composed, its prior, the identified preload, edits, the TCP stiffness."""
