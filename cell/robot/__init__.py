"""The robot controllers' programs, written from their plan by one writer per language."""
