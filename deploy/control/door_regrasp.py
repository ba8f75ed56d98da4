"""Where to hold a door's handle again, the hand turned back toward the robot, when the arc carried by a grasp that
turns with the door runs out of the arm's reach (pure functions, base frame, metres, radians, z up).

A vertical bar or a knob can be held at a range of yaws about the vertical line through its grip centre: the hand
turned back by a yaw toward the door's closed normal (toward the robot) holds the same handle, and the rest of the
arc then asks that much less turn of the wrist. How far the hand can turn is for the scene clearance to say, with the
door's plane where the door now stands."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.control.grasp import Handle
from deploy.geometry.clearance import ToolBox, depth_behind
from deploy.geometry.types import Axis

BAR_SAMPLES = 21  # a handle's bar is checked against the hand at this many points along it


def door_turn(axis: Axis, angle_rad: float) -> Rotation:
    """The door's turn by `angle_rad` about the (oriented) hinge direction: positive opens."""
    d = np.asarray(axis.direction, float)
    return Rotation.from_rotvec(d / np.linalg.norm(d) * angle_rad)


def held_centre(T_tool: np.ndarray, handle: Handle) -> np.ndarray:
    """The handle's grip centre as the holding arm tells it: `handle.depth_m` back from the tool frame along the
    approach (tool z)."""
    T = np.asarray(T_tool, float)
    return T[:3, 3] - handle.depth_m * T[:3, 2]


def held_as(T_tool: np.ndarray, handle: Handle) -> Handle:
    """`handle` as a tool at `T_tool` would hold it: its grip centre `handle.depth_m` before the tool frame along the
    approach (tool z), its front normal against the approach made horizontal, its bar along the tool's x (across the
    fingers' closing), so that `grasp_pose` on it at the tool's own tilt gives `T_tool` back."""
    T = np.asarray(T_tool, float)
    normal = -T[:3, 2].copy()
    normal[2] = 0.0
    return replace(handle, center=held_centre(T, handle), normal=normal / np.linalg.norm(normal), bar=T[:3, 0].copy())


def door_plane(handle: Handle, centre: np.ndarray, axis: Axis, opened_rad: float, relief_m: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(origin, outward unit normal) of the door's front where it now stands: the first frame's normal turned by
    `opened_rad`, through the point `relief_m` (how far the grip centre stands out of the front) behind `centre`."""
    normal = door_turn(axis, opened_rad).apply(handle.normal)
    normal /= np.linalg.norm(normal)
    return np.asarray(centre, float) - relief_m * normal, normal


def door_meets_hand(T_tool: np.ndarray, handle: Handle, axis: Axis, opened_rad: float, relief_m: float,
                    length_m: float, hand: tuple[ToolBox, ...]) -> bool:
    """Whether the door, opened `opened_rad`, reaches into the hand (`hand`'s boxes) at `T_tool` holding `handle`: a
    handle that turns between the pads lets the door turn against a hand that keeps its orientation, so that the
    handle's bar (`length_m` long, through the grip centre) swings its end toward the hand, and the front (`relief_m`
    behind the grip centre) reaches deeper into it than a front square to the hand does (a tilted grasp dips
    behind that one)."""
    centre = held_centre(T_tool, handle)
    square = door_plane(held_as(T_tool, handle), centre, axis, 0.0, relief_m)
    turned = door_plane(handle, centre, axis, opened_rad, relief_m)
    if depth_behind([T_tool], hand, *turned) > depth_behind([T_tool], hand, *square):
        return True
    bar = door_turn(axis, opened_rad).apply(handle.bar)
    along = np.linspace(-length_m / 2, length_m / 2, BAR_SAMPLES)
    local = (centre + along[:, None] * bar - T_tool[:3, 3]) @ np.asarray(T_tool, float)[:3, :3]
    return any(np.all(np.abs(local - box.centre) <= box.half, axis=1).any() for box in hand)


def opening_direction(axis: Axis, point: np.ndarray) -> np.ndarray:
    """The unit direction `point`, carried by the door, moves in as the door opens about the (oriented) hinge."""
    d = np.asarray(axis.direction, float)
    moving = np.cross(d / np.linalg.norm(d), np.asarray(point, float) - np.asarray(axis.origin, float))
    return moving / np.linalg.norm(moving)


def closing_push_n(opening_n: float, closing_n: float) -> float:
    """The force (N) a door pushes its handle toward closed with by itself (a self-closing hinge's spring), from the
    force the hand applies along the door's opening direction while it carries the door open and while it eases it
    back toward closed, as slowly: the door's friction adds to the first what it takes from the second, so their
    mean is the push alone (none for a door that stays where it is left)."""
    return (opening_n + closing_n) / 2.0
