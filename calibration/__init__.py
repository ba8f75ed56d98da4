"""axisloop: calibration."""
