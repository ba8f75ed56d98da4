"""axisloop drivers: what cameras and arms look like to the rest of the code."""
