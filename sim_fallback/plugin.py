"""Registers the simulated kinds (entry point `axisloop.plugins`): importing this module is cheap; the
simulator loads only when one of them is opened."""

from drivers.arm.registry import ARMS
from drivers.camera.registry import CAMERAS, STREAM_OPTIONS

CAMERAS.register("sim", "sim_fallback.devices:open_sim_camera", "simulated D415 (PyBullet)",
                 simulated=True, stream_options=STREAM_OPTIONS)
ARMS.register("sim", "sim_fallback.devices:open_sim_arm", "simulated Panda (PyBullet)", simulated=True)
ARMS.register("sim-can", "sim_fallback.devices:open_sim_can_arm",
              "the CAN driver on simulated Damiao motors (virtual bus)",
              simulated=True, bus="sim_fallback.devices:open_sim_can_bus")
