"""Axis estimators behind one protocol (`base.AxisEstimator`), chosen by name (`registry.ESTIMATORS`)."""
