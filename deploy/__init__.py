"""axisloop: deploy."""
