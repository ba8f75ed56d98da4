"""axisloop: sim_fallback."""
