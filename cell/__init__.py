"""The programs the cell loads, and their generators: the robot controllers' programs (KUKA KRL, ABB RAPID)."""
