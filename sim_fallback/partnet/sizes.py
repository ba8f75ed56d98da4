"""How big a model is as real furniture: one rule from its category's typical sizes.

PartNet-Mobility models come normalised (about 2 model units across their diagonal), whatever they show: a
microwave as wide as a wardrobe. `real_scale` picks the scale that puts the model's width, depth and height within
its category's typical ranges (below; ranges of common products: kitchen and storage units, appliances): the
geometric middle of the scales that satisfy all three, or, when none does, the scale closest to all three in log
size (least squares on how far each falls outside its range). Categories not listed use DEFAULT_RANGE_M.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

Range = tuple[tuple[float, float], tuple[float, float], tuple[float, float]]  # width, depth, height (m)

CATEGORY_RANGE_M: dict[str, Range] = {
    "StorageFurniture": ((0.30, 1.80), (0.30, 0.65), (0.30, 2.20)),  # from nightstands to wardrobes
    "Table": ((0.60, 2.00), (0.45, 1.00), (0.65, 0.95)),
    "Refrigerator": ((0.45, 0.95), (0.50, 0.80), (0.80, 2.00)),  # under-counter to full height
    "Microwave": ((0.40, 0.60), (0.30, 0.50), (0.25, 0.40)),
    "Oven": ((0.50, 0.80), (0.50, 0.70), (0.55, 0.95)),
    "Dishwasher": ((0.45, 0.60), (0.55, 0.65), (0.80, 0.90)),
    "WashingMachine": ((0.55, 0.70), (0.50, 0.75), (0.80, 1.00)),
    "Safe": ((0.30, 0.70), (0.30, 0.60), (0.25, 1.50)),
    "Printer": ((0.35, 0.60), (0.30, 0.60), (0.15, 0.50)),
    "TrashCan": ((0.25, 0.50), (0.25, 0.50), (0.30, 0.80)),
    "Door": ((0.60, 1.20), (0.03, 0.30), (1.80, 2.40)),
    "Window": ((0.50, 1.80), (0.05, 0.30), (0.50, 1.80)),
}
DEFAULT_RANGE_M: Range = ((0.30, 2.00), (0.30, 1.00), (0.30, 2.20))


def real_scale(size_native: np.ndarray, category: str) -> float:
    """The scale that makes a model of (width, depth, height) `size_native` (model units) the size of a real
    `category` piece (see the module's rule)."""
    size = np.maximum(np.asarray(size_native, dtype=float), 1e-6)
    ranges = np.array(CATEGORY_RANGE_M.get(category, DEFAULT_RANGE_M))
    low, high = np.log(ranges[:, 0] / size), np.log(ranges[:, 1] / size)  # log scales each dimension allows
    if low.max() <= high.min():
        return float(np.exp((low.max() + high.min()) / 2))

    def outside(u: float) -> float:
        return float(np.sum(np.maximum(low - u, 0.0) ** 2 + np.maximum(u - high, 0.0) ** 2))

    return float(np.exp(minimize_scalar(outside, bounds=(low.min(), high.max()), method="bounded").x))
