"""Simulated scenes the tests build: furniture standing side by side in front of the robot."""

import numpy as np

from sim_fallback.kitchen_scenario import KitchenScenario
from sim_fallback.layout import Layout, Placed, StaticShape
from sim_fallback.placement import CameraMount
from sim_fallback.start import Q_START


def showroom(furniture: list, task: str = "drawer") -> KitchenScenario:
    """The pieces side by side 2 m in front of the robot on a floor, facing it; the first one's first part the
    target."""
    placed, y = [], -1.5
    for f in furniture:
        placed.append(Placed(f, (2.0, y + f.size_m[0] / 2, 0.0, np.pi)))
        y += f.size_m[0] + 0.05
    floor = StaticShape("floor", "box", (4.0, 12.0, 0.02), (1.5, 0.0, -0.01, 0.0), None)
    layout = Layout(tuple(placed), (floor,), 0, furniture[0].parts[0].name)
    return KitchenScenario(task, 0, "test", layout, 0.0, CameraMount("tripod", (0.0, 0.5, 1.2), (2.0, 0.0, 0.5)),
                           tuple(Q_START), "normal")
