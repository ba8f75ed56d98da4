"""A kitchen scenario: a seeded kitchen (sim_fallback/kitchen.py), the target part in it, the robot parked in front of
that part (sim_fallback/placement.py), the camera, and the arm's start. Pure values; `SimWorld` builds them.

Robot base frame = world frame: origin at the Panda's base, x forward, z up; the floor lies `base_height_m` below.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.arm.grasping import FROM_ABOVE_RAD, GRASP_PITCH_RAD
from drivers.arm.kinematics import Kinematics, grasps_grip
from drivers.arm.robot_config import load_robot_config
from drivers.arm.robots import PANDA_REACH, Reach
from sim_fallback.covered import covering_part
from sim_fallback.errors import PartError, SceneError
from sim_fallback.furniture import Finish, Furniture, PartKind
from sim_fallback.furniture_body import PartGeometry, measure_parts
from sim_fallback.kitchen import Room, random_room, random_target, role_of, standing_height
from sim_fallback.layout import Layout, Placed, StaticShape
from sim_fallback.parts import ordered, resolve
from sim_fallback.placement import (
    ARM_AT_START,
    BASE_HEIGHT_M,
    CLEARANCE_M,
    STAND_HALF_M,
    TRIPOD_HEIGHT_M,
    CameraMount,
    Obstacle,
    arm_at_start,
    base_heights,
    overlap,
    park_robot,
    place_camera,
)
from sim_fallback.start import CONDITIONS, Condition, random_start
from sim_fallback.unit_families import Split, random_look

ATTEMPTS = 30  # kitchens drawn for one seed until the target has a reachable part as asked
OPENED = {"drawer": 0.3, "door": float(np.radians(45.0))}  # the grip stays in view opened this far
PARKINGS = 20  # robot parkings drawn until the part opens as asked clear of the robot and the arm grasps it
ARM_COLUMN_M = 0.35  # the arm's base and shoulder stand this high above its base plate (the Panda's shoulder: 0.333 m)
ARM_BASE_HALF_M = 0.11  # and this far either side of its axis (the Panda's base: about 0.2 m across)
PARK_APPROACH_M, PARK_PULL_M = 0.1, 0.05  # a parking lets the arm approach the grip this far straight in (the
# episode's default approach) and pull it this far straight out (the shortest pull its grasp planner asks for)
SCAN_STEP_M = 0.02  # a short pull's band is scanned down in height and across in distance this finely
SWEEP_STEPS = 10  # the part's openings checked against the robot, from closed to the task's
HAND_ABOVE_M = 0.15  # a hand grasping a drawer's level bar from above reaches this far above the grip (the Panda's
# hand, 0.2 m along the way its fingers close, stands tilted up along it)
RECORD_ABOVE_M = (0.2, 0.6)  # a recording's tripod head stands this far above the part's front centre
TRIPOD_LOW_M = 0.5  # and at least this high above the floor (a tripod's lowest comfortable setting)
GRIP_BAND_M = 0.4  # a front no mount sees whole (a tall door) need only be seen this far above and below its grip
STAND = Finish("painted", (0.25, 0.25, 0.27), 0.3, 0)
SPLITS, KINDS = ("train", "test"), ("drawer", "door")


@dataclass(frozen=True)
class KitchenScenario:
    """One episode's set-up in a kitchen: the `kitchen` in the robot base frame (the target part `kitchen.part` in
    `kitchen.target_furniture`), the robot base's height above the floor, the camera, the arm's start (rad) and the
    target joint's `condition` ("locked": held fast; "stiff": three times its friction and stiction)."""

    task: PartKind
    seed: int
    split: Split
    kitchen: Layout
    base_height_m: float
    camera: CameraMount
    q_start: tuple[float, ...]
    condition: Condition = "normal"

    world = "kitchen"

    @property
    def part(self) -> str:
        return self.kitchen.part

    def build_layout(self, floor: bool = False) -> Layout:
        """The kitchen (it has its own floor: `floor` changes nothing)."""
        return self.kitchen

    @property
    def T_base_camera(self) -> np.ndarray:
        """Camera pose in the base frame, OpenCV optical axes (x right, y down, z forward)."""
        return self.camera.T_base_camera

    @classmethod
    def make(cls, task: PartKind, seed: int, split: Split = "train", part: str | None = None,
             target: Furniture | None = None, condition: Condition = "normal", style: str | None = None,
             reach: Reach = PANDA_REACH, opening: float = 0.0) -> KitchenScenario:
        """A kitchen scenario, deterministic from (task, seed, split) and the arguments. `part`: the `--part` text
        (default: the seed picks a reachable part of the task's kind that opens at least `opening`, m or rad: the
        task's target); `target`: the furniture to open (default: a
        procedural unit of the split's family, drawn again until it has that part within the usual bands of reach);
        `style`: every procedural unit's handle style (default: drawn); `reach`: the arm's (default: the Panda's; a
        given `target` with no part in its usual bands is placed in its bands from above). SceneError when
        the part is not there or out of reach."""
        if condition not in CONDITIONS or task not in KINDS or split not in SPLITS:
            raise SceneError(f"kitchen scenario {task!r}/{split!r}/{condition!r}: the task is one of {KINDS}, the "
                             f"split one of {SPLITS}, the condition one of {CONDITIONS}")
        rng = np.random.default_rng([SPLITS.index(split), KINDS.index(task), seed, 2])
        reach = reach if target is not None else reach.usual()  # a unit with no part at a comfortable height is
        # drawn again rather than grasped from above
        source = f"procedural {split} {seed}"
        error: SceneError | None = None
        for _ in range(ATTEMPTS):
            look = random_look(split, rng, style)
            role, furniture = random_target(task, split, look, rng, source) if target is None else \
                (role_of(target), target)
            room = random_room(furniture, role, split, look, rng, source)
            try:
                chosen, part_reach = _choose_part(room, task, part, rng, reach, opening)
                return _park(cls, task, seed, split, room, chosen, condition, part_reach, opening)
            except PartError as exc:
                if target is not None:  # another kitchen would not change its parts nor their heights
                    raise
                error = exc
            except SceneError as exc:
                error = exc
        raise error  # type: ignore[misc]


def _choose_part(room: Room, task: PartKind, text: str | None, rng: np.random.Generator,
                 reach: Reach, opening: float) -> tuple[PartGeometry, Reach]:
    """The target part and the reach it is placed in (`placing_reach`): the one `text` names (placed in the reach
    its own grip calls for: a user who names a low part grasps it from above), else one of the task's kind within
    that reach that opens at least `opening`, drawn from `rng`."""
    placed = room.furniture[room.target]
    geometry = measure_parts(placed.furniture)
    if text is not None:
        chosen = resolve(placed.furniture, geometry, task, text)
        placing = named_reach(placed, chosen, task, reach, opening)
        roomy = _roomy(geometry, task, reach, placing)
        cover = covering_part(chosen, geometry)
        if cover is not None:
            raise PartError(f"--part {text!r}: {chosen.name} of {placed.furniture.source} stands behind its {cover}'s "
                            f"front: a pull from outside cannot reach it; name another part")
        if chosen.name not in {g.name for g in roomy}:
            raise PartError(f"--part {text!r}: {chosen.name} of {placed.furniture.source} is grasped from above here "
                            f"and its furniture stands {chosen.room_above_m:.2f} m above its grip, less than the "
                            f"{HAND_ABOVE_M:g} m the hand needs; name another part")
        if base_heights(_grip_height(placed, chosen), task, placing) is None:
            raise PartError(f"--part {text!r}: {chosen.name} of {placed.furniture.source} is out of the robot's "
                             f"reach: {_reach(placed, [chosen], task, reach)}")
        return chosen, placing
    placing = placing_reach(placed, geometry, task, reach, opening)
    reachable = reachable_parts(placed, _roomy(geometry, task, reach, placing), task, placing, opening)
    if not reachable:
        raise PartError(_no_part(placed, geometry, task, reach, opening))
    return reachable[int(rng.integers(len(reachable)))], placing


def placing_reach(placed: Placed, geometry: list[PartGeometry], task: PartKind, reach: Reach,
                  opening: float = 0.0) -> Reach:
    """The reach the furniture's parts are placed in: the first of `reach`, its usual grasp lowered for a pull of
    `opening` (`short_pull_reach`) and its reach from above (a user grasps a low handle from above only when nothing
    is at a comfortable height) in which some part of the task's kind that opens at least `opening` lies (a drawer
    grasped from above with room for a hand above its grip), else `reach`."""
    for placing in _reaches(reach, task, opening):
        if reachable_parts(placed, _roomy(geometry, task, reach, placing), task, placing, opening):
            return placing
    return reach


def named_reach(placed: Placed, part: PartGeometry, task: PartKind, reach: Reach, opening: float = 0.0) -> Reach:
    """The reach a part a user names is placed in: the first of `reach`, its usual grasp lowered for a pull of
    `opening` and its reach from above whose bands hold its grip (a user who names a low part grasps it from above,
    whatever the other parts' heights), else `reach`."""
    grip = _grip_height(placed, part)
    return next((r for r in _reaches(reach, task, opening) if base_heights(grip, task, r) is not None), reach)


def _reaches(reach: Reach, task: PartKind, opening: float) -> list[Reach]:
    """The reaches a part is placed in, in the order a user tries them: `reach`, its usual grasp lowered for a pull
    of `opening`, its reach from above (those the arm has)."""
    return [r for r in (reach, short_pull_reach(reach, task, opening), reach.from_above(task)) if r is not None]


def _roomy(geometry: list[PartGeometry], task: PartKind, reach: Reach, placing: Reach) -> list[PartGeometry]:
    """The parts a hand can grasp when placed in `placing`: all, but for a reach from above (`room_from_above`)."""
    return room_from_above(geometry) if placing != reach and placing == reach.from_above(task) else geometry


def room_from_above(geometry: list[PartGeometry]) -> list[PartGeometry]:
    """The parts a hand can grasp from above: doors, and drawers whose furniture leaves HAND_ABOVE_M free above
    the grip (not under a tabletop)."""
    return [g for g in geometry if g.kind != "drawer" or g.room_above_m >= HAND_ABOVE_M]


def reach_problem(furniture: Furniture, task: PartKind, reach: Reach = PANDA_REACH, opening: float = 0.0) -> str | None:
    """Why `furniture`, standing where a given target does at the lowest (the floor, or a countertop:
    `standing_height`), has no part of the task's kind that opens at least `opening` (m or rad) and an arm of
    `reach` can reach (one line); None when it has one."""
    placed, geometry = Placed(furniture, (0.0, 0.0, standing_height(furniture), 0.0)), measure_parts(furniture)
    placing = placing_reach(placed, geometry, task, reach, opening)
    if reachable_parts(placed, _roomy(geometry, task, reach, placing), task, placing, opening):
        return None
    return _no_part(placed, geometry, task, reach, opening)


def reachable_parts(placed: Placed, geometry: list[PartGeometry], task: PartKind, reach: Reach,
                    opening: float = 0.0) -> list[PartGeometry]:
    """The parts of the task's kind (in a user's order) that open at least `opening` (m or rad), stand behind no
    other part's front (`covering_part`) and whose grip some robot base height brings into `reach`."""
    return [g for g in ordered(geometry, task) if placed.furniture.part(g.name).upper >= opening
            and covering_part(g, geometry) is None and base_heights(_grip_height(placed, g), task, reach) is not None]


def _no_part(placed: Placed, geometry: list[PartGeometry], task: PartKind, reach: Reach, opening: float) -> str:
    """Why no part serves: none opens as far as asked, else all that do stand behind another part's front, else
    none is within reach."""
    parts = [placed.furniture.part(g.name) for g in ordered(geometry, task)]
    if parts and all(p.upper < opening for p in parts):
        most = max(p.upper for p in parts)
        far, asked = (f"{most:.2f} m", f"{opening:.2f} m") if task == "drawer" else \
            (f"{np.degrees(most):.0f} deg", f"{np.degrees(opening):.0f} deg")
        return (f"{placed.furniture.source}: its {task}s open at most {far}, less than the {asked} asked: ask for "
                f"less, or choose another object")
    hidden = {g.name: covering_part(g, geometry) for g in ordered(geometry, task)
              if placed.furniture.part(g.name).upper >= opening}
    if hidden and all(hidden.values()):
        behind = ", ".join(f"{name} behind its {cover}" for name, cover in hidden.items())
        return (f"{placed.furniture.source} cannot be used for a {task}: its {task}s stand behind another part's "
                f"front as seen from outside ({behind}), where a pull cannot reach them; choose another object")
    return (f"{placed.furniture.source} has no {task} within the robot's reach: "
            f"{_reach(placed, ordered(geometry, task), task, reach)}")


def _grip_height(placed: Placed, part: PartGeometry) -> float:
    return float((placed.T @ [*part.grip, 1.0])[2])


def _reach(placed: Placed, parts: list[PartGeometry], task: str, reach: Reach) -> str:
    heights = ", ".join(f"{g.name} {_grip_height(placed, g):.2f} m{_covered_above(g)}" for g in parts) or \
        f"it has no {task}"
    (low, high), (base_low, base_high) = reach.height(task), BASE_HEIGHT_M
    return (f"its grips stand above the floor at {heights}; the robot reaches {task} grips {low + base_low:.2f}-"
            f"{high + base_high:.2f} m above the floor (its base {base_low:g}-{base_high:g} m up, the grip "
            f"{low:g}-{high:g} m above the base){_from_above(reach, task)}: name another part, or give another seed")


def _from_above(reach: Reach, task: str) -> str:
    low = reach.from_above(task)
    if low is None:
        return ""
    (lo, hi), (base_low, base_high) = low.height(task), BASE_HEIGHT_M
    return (f", and from above {lo + base_low:.2f}-{hi + base_high:.2f} m for a part named or when no grip is in "
            f"that band, and a drawer's has {HAND_ABOVE_M:g} m free above it for the hand")


def _covered_above(part: PartGeometry) -> str:
    if part.kind != "drawer" or part.room_above_m >= HAND_ABOVE_M:
        return ""
    return f" (the furniture {part.room_above_m:.2f} m above it)"


def _park(cls: type[KitchenScenario], task: PartKind, seed: int, split: Split, room: Room, part: PartGeometry,
          condition: Condition, reach: Reach, opening: float) -> KitchenScenario:
    """The robot parked in front of `part` (its grip in `reach`) where the part opens to `opening` (m or rad)
    without passing through the robot's stand or arm column, the arm grasps it (`arm_grasps`) and a camera sees it
    past the arm, as a user parks it; the camera placed; all in the robot base frame."""
    rng = np.random.default_rng([SPLITS.index(split), KINDS.index(task), seed, 3])
    placed = room.furniture[room.target]
    T_room = placed.T
    grip = (T_room @ [*part.grip, 1.0])[:3]
    normal = T_room[:3, :3] @ part.normal
    others = [p.footprint() for k, p in enumerate(room.furniture) if k != room.target]
    others += [s.footprint() for s in room.statics if s.name != "floor"]  # walls too: a corner's side wall
    lo, hi = base_heights(_grip_height(placed, part), task, reach)  # type: ignore[misc]
    error = SceneError(f"{placed.furniture.source}, {part.name}: no parking spot in reach lets the arm grasp it "
                       "and it open clear of the robot's stand and arm; give another seed")
    for _ in range(PARKINGS):
        try:
            T = park_robot(grip, normal, task, others, rng, reach)
        except ValueError as exc:
            raise SceneError(f"{placed.furniture.source}, {part.name}: {exc}") from None
        height = float(rng.uniform(lo, hi))
        T[2, 3] = -height
        if meets_robot(part, T @ T_room, height, opening) or not arm_grasps(reach, T, grip, normal):
            continue
        layout = Layout(tuple(room.furniture), tuple(room.statics), room.target, part.name).moved(T)
        if height > 0.01:
            stand = StaticShape("robot stand", "box", (2 * STAND_HALF_M, 2 * STAND_HALF_M, height - 0.002),
                                (0.0, 0.0, -height / 2 - 0.001, 0.0), STAND)
            layout = Layout(layout.furniture, (*layout.statics, stand), layout.target, layout.part)
        try:  # a parking from which no camera sees the part past the arm at its start is parked again
            camera = _camera(layout, part, T @ T_room, -height, task, rng, arm_at_start(reach, task))
        except SceneError as exc:
            error = exc
            continue
        return cls(task, seed, split, layout, height, camera, random_start(rng), condition)
    raise error


def arm_grasps(reach: Reach, T_base_room: np.ndarray, grip: np.ndarray, normal: np.ndarray) -> bool:
    """Whether the arm of `reach.model` (None: any arm, the bands alone) parked at `T_base_room` grasps the grip
    (room frame) on its front facing `normal` and pulls it PARK_PULL_M out (`grasps_grip`), at the usual pitch or
    from above: the bands are a box, the arm's reach is not."""
    if reach.model is None:
        return True
    kin, q_ready = _arm_model(reach.model)
    grip_base = T_base_room[:3, :3] @ grip + T_base_room[:3, 3]
    normal_base = T_base_room[:3, :3] @ normal
    return any(grasps_grip(kin, q_ready, grip_base, normal_base, pitch, PARK_APPROACH_M, PARK_PULL_M)
               for pitch in (GRASP_PITCH_RAD, *FROM_ABOVE_RAD))


def short_pull_reach(reach: Reach, task: PartKind, opening: float) -> Reach | None:
    """The usual grasp of a drawer pulled only `opening` (at least PARK_PULL_M), shorter than the pull its drawer
    bands are set for (`reach.drawer_pull_m`): the same distance band, the height band lowered to the lowest height
    down to which the arm of `reach.model` grasps the grip and pulls it that far at every distance of the band (a
    short pull leaves the arm clear of its joint limits lower down). None for a door, an arm with no model, a pull
    as long as the bands', or one the arm carries no lower."""
    pull = max(opening, PARK_PULL_M)
    if task != "drawer" or reach.model is None or pull >= reach.drawer_pull_m:
        return None
    low, high = reach.drawer_height_m
    lowest = _lowest_grip(reach.model, reach.drawer_distance_m, low, round(pull, 3))
    return None if lowest >= low else replace(reach, drawer_height_m=(lowest, high))


@functools.cache
def _lowest_grip(model: str, distance_m: tuple[float, float], height_m: float, pull_m: float) -> float:
    """The lowest height, down from `height_m` in SCAN_STEP_M steps, to which every height grasps a grip at each
    distance of `distance_m` (SCAN_STEP_M apart) facing the arm and pulls it `pull_m` straight out, at the usual
    pitch (`grasps_grip`)."""
    kin, q_ready = _arm_model(model)
    distances = np.linspace(*distance_m, int(np.ceil((distance_m[1] - distance_m[0]) / SCAN_STEP_M)) + 1)
    height = height_m
    while height - SCAN_STEP_M > 0.0 and all(
            grasps_grip(kin, q_ready, np.array([d, 0.0, height - SCAN_STEP_M]), np.array([-1.0, 0.0, 0.0]),
                        GRASP_PITCH_RAD, PARK_APPROACH_M, pull_m) for d in distances):
        height -= SCAN_STEP_M
    return round(float(height), 3)


@functools.cache
def _arm_model(model: str) -> tuple[Kinematics, np.ndarray]:
    config = load_robot_config(model)
    return config.kinematics(), np.array(config.q_ready)


def meets_robot(part: PartGeometry, T_base_furniture: np.ndarray, base_height: float, opening: float) -> bool:
    """Whether `part` (its furniture at `T_base_furniture`), opened from closed to `opening` (m or rad), passes
    through the robot's stand (a square STAND_HALF_M across under the base plate, `base_height` down to the floor)
    or its arm's column (ARM_BASE_HALF_M across, ARM_COLUMN_M up from the base plate), where no arm posture gives
    way."""
    for corners in swept_boxes(part, opening):
        c = corners @ T_base_furniture[:3, :3].T + T_base_furniture[:3, 3]
        footprint = c[[0, 2, 6, 4], :2]
        for half, low, high in ((STAND_HALF_M, -base_height, 0.0), (ARM_BASE_HALF_M, 0.0, ARM_COLUMN_M)):
            square = (half - CLEARANCE_M) * np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, -1.0], [-1.0, 1.0]])
            if c[:, 2].min() < high and c[:, 2].max() > low and overlap(footprint, square):  # touching, not near
                return True
    return False


def swept_boxes(part: PartGeometry, opening: float) -> list[np.ndarray]:
    """The part's box corners (furniture frame, `PartGeometry.corners` order) at SWEEP_STEPS openings from closed to
    `opening`: a drawer slid out along its normal; a door turned outward about the back of its vertical edge farthest
    from its grip (its hinge)."""
    corners = part.corners()
    if part.kind == "drawer":
        return [corners + s * part.normal for s in np.linspace(0.0, opening, SWEEP_STEPS)]
    sideways = np.cross([0.0, 0.0, 1.0], part.normal)
    lateral, grip = corners @ sideways, part.grip @ sideways
    edge = max((lateral.min(), lateral.max()), key=lambda e: abs(grip - e))
    pivot = edge * sideways + (corners @ part.normal).min() * part.normal
    turn = -np.sign(grip - edge)  # the grip moves out along the normal
    return [(corners - pivot) @ Rotation.from_rotvec([0.0, 0.0, turn * a]).as_matrix().T + pivot
            for a in np.linspace(0.0, opening, SWEEP_STEPS)]


def recording_camera(scenario: KitchenScenario) -> CameraMount:
    """The camera of a recording of `scenario`'s part (`deploy sim record`): for a low part, one whose front centre
    stands too low for a tripod at its usual height (TRIPOD_HEIGHT_M) to stand within RECORD_ABOVE_M above it, a
    tripod lowered as a user filming the part lowers it: its head RECORD_ABOVE_M above the front centre, at least
    TRIPOD_LOW_M above the floor (mounted as `_camera` does), so that the part is seen from near its own height,
    not from 1.2-1.8 m up across the room; else, or when no such mount sees it, the scenario's camera."""
    layout = scenario.kitchen
    placed = layout.target_furniture
    [part] = [g for g in measure_parts(placed.furniture) if g.name == layout.part]
    floor_z = -scenario.base_height_m
    centre_up = float((placed.T @ [*part.front_centre, 1.0])[2]) - floor_z
    if centre_up + RECORD_ABOVE_M[1] >= TRIPOD_HEIGHT_M[0]:
        return scenario.camera
    tripod = (max(centre_up + RECORD_ABOVE_M[0], TRIPOD_LOW_M), max(centre_up + RECORD_ABOVE_M[1], TRIPOD_LOW_M))
    rng = np.random.default_rng([SPLITS.index(scenario.split), KINDS.index(scenario.task), scenario.seed, 4])
    try:
        return _camera(layout, part, placed.T, floor_z, scenario.task, rng, ARM_AT_START, tripod)
    except SceneError:
        return scenario.camera


def _camera(layout: Layout, part: PartGeometry, T_base_furniture: np.ndarray, floor_z: float, task: PartKind,
            rng: np.random.Generator, arm: Obstacle, tripod_m: tuple[float, float] = TRIPOD_HEIGHT_M) -> CameraMount:
    """A camera that sees the part's front closed and its grip opened by OPENED[task], past the `arm` at its start; for
    a front no mount sees whole, its band within GRIP_BAND_M of the grip; a tripod's head `tripod_m` above the
    floor."""
    def base(points: np.ndarray) -> np.ndarray:
        return np.asarray(points) @ T_base_furniture[:3, :3].T + T_base_furniture[:3, 3]

    opened = part.grip + OPENED[task] * part.normal if task == "drawer" else _swung(part, OPENED[task])
    corners = part.corners()
    front = corners[corners @ part.normal >= part.front_centre @ part.normal - 1e-6]
    near_grip = front.copy()  # a front too tall to see whole: the band of it around its grip
    near_grip[:, 2] = np.clip(front[:, 2], part.grip[2] - GRIP_BAND_M, part.grip[2] + GRIP_BAND_M)
    obstacles = [(p.footprint(), *p.heights) for k, p in enumerate(layout.furniture) if k != layout.target]
    obstacles += [(s.footprint(), *s.heights) for s in layout.statics if s.name != "floor"]
    for seen in (front, near_grip):
        try:
            return place_camera(base(part.front_centre), base(part.grip), T_base_furniture[:3, :3] @ part.normal,
                                base(np.vstack([seen, opened])), floor_z, obstacles, rng, arm, tripod_m=tripod_m)
        except ValueError as exc:
            error = exc
    raise SceneError(f"{layout.target_furniture.furniture.source}, {part.name}: {error}") from None


def _swung(part: PartGeometry, angle: float) -> np.ndarray:
    """The grip of a door opened by `angle`, turned about the front's vertical edge farthest from it (its hinge)."""
    sideways = np.cross([0.0, 0.0, 1.0], part.normal)
    lateral = part.corners() @ sideways
    grip = part.grip @ sideways
    r = grip - max((lateral.min(), lateral.max()), key=lambda edge: abs(grip - edge))
    return part.grip + r * (np.cos(angle) - 1.0) * sideways + abs(r) * np.sin(angle) * part.normal
