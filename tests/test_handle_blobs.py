"""Handle candidates on a front's rectified view, on a synthetic D415 frame: a long thin bar the D415 lost (seen in
colour only) whose end nearly touches the depth hole along the front's side edge (the IR shadow a D415 leaves beside
a depth edge) is still one handle, not part of a shape too large for one; a bar standing out across a drawer's whole
width is a handle, a ledge running on past the front's ends is not; a sliver too short for a bar and too thin for a
knob is no firm handle, a knob is; a pull's pocket running under a counter's edge that hides the front's top is
seen whole up to that edge; a dark line without depth along the front's side is no handle seen in colour only; a
bump on a bowed panel, or a dip in a recessed window, is no firm handle when it stands out of the surface around it
by less than a handle does; a strip along the side where the front's surface stops, standing out no farther than the
unit beside it, is that unit's edge, not a handle; two tabs side by side, one a centimetre higher, are two handles."""

from __future__ import annotations

import numpy as np

from deploy.perception.front_extent import Extent
from deploy.perception.handle_blobs import handle_blobs
from deploy.perception.plane_view import PlaneFrame, rectify
from drivers.camera.base import Frame, Intrinsics

K = Intrinsics(640, 480, 600.0, 600.0, 320.0, 240.0)
FRONT_U, FRONT_V = (170, 470), (140, 340)  # the front's pixels, 1 m straight ahead: 0.5 x 0.33 m


def _frame(bar_u: tuple[int, int], bar_depth: float = 0.0, ledge: bool = False) -> Frame:
    """A brown front 1 m ahead before a wall 1.3 m away; a grey bar without depth 4 cm under its top at columns
    `bar_u` (or standing out at `bar_depth`); no depth and dark along its left edge, just outside it (the IR shadow);
    with `ledge`, a counter's edge 3 cm out across the whole image 2 cm over the front's top."""
    depth = np.full((480, 640), 1.3, np.float32)
    color = np.full((480, 640, 3), 200, np.uint8)
    front = (slice(*FRONT_V), slice(*FRONT_U))
    depth[front], color[front] = 1.0, (150, 100, 60)
    bar = (slice(FRONT_V[0] + 24, FRONT_V[0] + 30), slice(*bar_u))
    depth[bar], color[bar] = bar_depth, (128, 128, 128)
    if ledge:
        depth[FRONT_V[0] - 20:FRONT_V[0] - 12], color[FRONT_V[0] - 20:FRONT_V[0] - 12] = 0.97, (150, 100, 60)
    shadow = (slice(*FRONT_V), slice(FRONT_U[0] - 12, FRONT_U[0]))
    depth[shadow], color[shadow] = 0.0, (30, 30, 30)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # optical z along base x
    return Frame(0, 0.0, color, depth, K, T)


def _blobs(bar_u: tuple[int, int], bar_depth: float = 0.0, ledge: bool = False) -> list:
    return _blobs_of(_frame(bar_u, bar_depth, ledge))


def _blobs_of(frame: Frame, right: str = "gap", right_u: int = FRONT_U[1]) -> list:
    """The candidates on the front FRONT_U x FRONT_V (or up to pixel column `right_u`), its right side ended `right`."""
    plane = PlaneFrame.facing(np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]), np.zeros(3))
    view = rectify(frame, np.zeros((480, 640), bool), plane, (-0.35, 0.35), (-0.25, 0.25), 1.0 / K.fx)
    s = (np.array([FRONT_U[0], right_u]) - K.cx) / K.fx
    z = (K.cy - np.array(FRONT_V)) / K.fy
    extent = Extent(int(view.row(z[0])) + 1, int(view.row(z[1])) - 1, int(view.col(s[0])) + 1, int(view.col(s[1])) - 1,
                    {**dict.fromkeys(("top", "bottom", "left"), "gap"), "right": right})
    return handle_blobs(view, extent, frame.T_base_camera, K.K)


def _bars(bar_u: tuple[int, int], bar_depth: float = 0.0, length_m: float = 0.35) -> list:
    return [b for b in _blobs(bar_u, bar_depth) if b.firm and b.inside and b.length_m > length_m]


def test_a_long_bar_beside_the_side_edges_shadow_is_one_handle():
    assert len(_bars((FRONT_U[0] + 20, FRONT_U[1] - 40))) == 1  # clear of the shadow
    assert len(_bars((FRONT_U[0] + 4, FRONT_U[1] - 40))) == 1  # its end 4 px (7 mm) from the shadow


def test_a_bar_standing_out_across_a_drawers_whole_width_is_its_handle():
    bars = _bars((FRONT_U[0] + 3, FRONT_U[1] - 3), bar_depth=0.97, length_m=0.45)  # 0.49 of the 0.5 m front
    assert len(bars) == 1 and bars[0].relief_m > 0.02


def test_a_ledge_running_on_past_the_fronts_ends_is_no_handle():
    blobs = _blobs((FRONT_U[0] + 20, FRONT_U[1] - 40), ledge=True)
    assert not [b for b in blobs if b.relief_m > 0.02 and b.length_m > 0.35]


def _plain_frame(patches: list[tuple[slice, slice, float]]) -> Frame:
    """A brown front 1 m ahead before a wall 1.3 m away, with `patches` (rows, columns, depth) of the same colour."""
    frame = _frame((FRONT_U[0] + 20, FRONT_U[0] + 21))
    depth, color = frame.depth_m.copy(), frame.color.copy()
    depth[FRONT_V[0] + 24:FRONT_V[0] + 30, FRONT_U[0] + 20:FRONT_U[0] + 21] = 1.0  # no bar
    color[slice(*FRONT_V), slice(*FRONT_U)] = (150, 100, 60)
    for rows, cols, d in patches:
        depth[rows, cols] = d
    return Frame(0, 0.0, color, depth, K, frame.T_base_camera)


def _firm_at(blobs: list, u: int, v: int) -> list:
    """The firm candidates centred within 3 cm of pixel (u, v)'s point on the front."""
    at = np.array([(u - K.cx) / K.fx, (K.cy - v) / K.fy])
    return [b for b in blobs if b.firm and np.linalg.norm(b.centre - at) < 0.03]


def test_a_sliver_too_short_for_a_bar_and_too_thin_for_a_knob_is_no_firm_handle():
    u, v = 320, 240  # 2.6 x 1.0 cm standing 1.5 cm out (a noise ridge or a seam); a 2.8 cm knob head 2 cm out
    sliver = [(slice(v - 3, v + 4), slice(u - 9, u + 10), 0.985)]
    knob = [(slice(v - 8, v + 9), slice(u - 8, u + 9), 0.98)]
    assert not _firm_at(_blobs_of(_plain_frame(sliver)), u, v)
    assert len(_firm_at(_blobs_of(_plain_frame(knob)), u, v)) == 1


def test_a_pocket_running_under_what_hides_the_fronts_top_keeps_its_upper_part():
    top = FRONT_V[0]  # a counter's edge 3 cm out hides the front down to its top row, where a pull's pocket (3 cm
    # deep, 20 x 6.7 cm seen) begins: the pocket is whole, not cut 2 cm short of the edge as one inside the panel is
    pocket = [(slice(top, top + 40), slice(260, 380), 1.03), (slice(top - 20, top), slice(0, 640), 0.97)]
    blobs = [b for b in _blobs_of(_plain_frame(pocket)) if b.firm and b.relief_m < -0.02]
    assert len(blobs) == 1
    assert blobs[0].across_m > 0.06  # its whole 6.7 cm from the front's top (4.7 cm cut short)


def test_a_knob_is_where_its_head_is_not_its_rims_mixed_depth_along_the_line_of_sight():
    u, v = 320, 240  # a 2.8 cm knob head 3 cm out; beside it, 4 cm of its rim's pixels mixing its depth with the
    # front's (1.5 cm out), as a D415 seeing it obliquely gives
    knob = [(slice(v - 8, v + 9), slice(u - 8, u + 9), 0.97), (slice(v + 9, v + 20), slice(u - 8, u + 16), 0.985),
            (slice(v - 8, v + 20), slice(u + 9, u + 32), 0.985)]
    (blob,) = _firm_at(_blobs_of(_plain_frame(knob)), u, v)
    head = np.array([(u - K.cx) / K.fx, (K.cy - v) / K.fy]) * 0.97
    assert np.linalg.norm(blob.centre - head) < 0.005 and blob.length_m < 0.04


def test_a_dark_line_without_depth_along_the_fronts_side_is_no_handle():
    """A dark band without depth 5 px (8 mm) wide, 7 px (1.2 cm) inside the front's left side, the front's whole
    height (a bevelled edge seen at a slant, or the gap's line there). Seen in colour only and running along the side,
    it is that edge, no handle; a thin dark bar without depth 6 cm in from the side still is one."""
    line = slice(FRONT_U[0] + 7, FRONT_U[0] + 12)
    frame = _plain_frame([(slice(*FRONT_V), line, 0.0)])
    frame.color[slice(*FRONT_V), line] = (30, 30, 30)
    u, v = FRONT_U[0] + 9, (FRONT_V[0] + FRONT_V[1]) // 2
    assert not _firm_at(_blobs_of(frame), u, v)
    frame.depth_m[FRONT_V[0] + 40:FRONT_V[1] - 40, u + 36:u + 41] = 0.0
    frame.color[FRONT_V[0] + 40:FRONT_V[1] - 40, u + 36:u + 41] = (30, 30, 30)
    assert len(_firm_at(_blobs_of(frame), u + 38, v)) == 1


def test_a_bump_on_a_bowed_panel_or_a_dip_in_a_recessed_window_is_no_firm_handle():
    """A 6.7 x 2.8 cm patch 1.7 cm off the plane is a firm handle on a flat panel; on a 33 x 20 cm stretch of the
    panel 7 mm off the plane the same way (a fridge's bowed door, a microwave's window set in), it stands 1 cm out of
    the surface around it, within the depth's noise: no handle."""
    u, v = 320, 240
    for sign in (-1, 1):  # standing out, sunk in
        patch = (slice(v - 8, v + 9), slice(u - 20, u + 21), 1.0 - sign * 0.017)
        assert len(_firm_at(_blobs_of(_plain_frame([patch])), u, v)) == 1
        panel = (slice(v - 60, v + 61), slice(u - 100, u + 101), 1.0 - sign * 0.007)
        assert not _firm_at(_blobs_of(_plain_frame([panel, patch])), u, v)


def test_a_strip_along_the_side_standing_out_no_farther_than_the_unit_beside_is_no_handle():
    """Past the front's right side, where its surface stops, a unit stands 2.5 cm out of it; along that side, 11 cm of
    the front's edge 1.8 cm out (the smoothed depth blending the two, or a ridge of noise there). What stands out
    there no farther than the unit beside it is that unit's edge, no handle (before: a firm candidate, which cut a
    door away from its own knob). A bar on a door's very edge, with the room past it, is still one (test_pointer)."""
    u, v = FRONT_U[1] - 4, (FRONT_V[0] + FRONT_V[1]) // 2
    strip = (slice(v - 33, v + 33), slice(FRONT_U[1] - 8, FRONT_U[1]), 0.982)
    beside = (slice(*FRONT_V), slice(FRONT_U[1], FRONT_U[1] + 60), 0.975)
    assert not _firm_at(_blobs_of(_plain_frame([strip, beside]), right="surface"), u, v)
    bar = (slice(v - 3, v + 4), slice(FRONT_U[1] - 120, FRONT_U[1] - 5), 0.97)  # a long bar across, ending by the side
    assert _firm_at(_blobs_of(_plain_frame([bar, beside]), right="surface"), FRONT_U[1] - 60, v)


def test_a_strip_sunk_along_the_side_next_to_a_unit_standing_out_is_no_pull():
    """Past the front's right side a wall stands 4 cm out, its first 5 mm close enough to the plane to be taken for
    the front's surface; inside the side, 4.5 cm of the front sunk 3 cm (the carcass's edge between the door and the
    wall). That strip is the gap to what stands beside the front, not a pull's pocket cut into the panel (before: a
    firm pocket, which cut a door away from its own knob)."""
    u, v = FRONT_U[1] - 16, (FRONT_V[0] + FRONT_V[1]) // 2
    strip = (slice(v - 20, v + 20), slice(FRONT_U[1] - 30, FRONT_U[1] - 3), 1.03)
    ramp = (slice(*FRONT_V), slice(FRONT_U[1], FRONT_U[1] + 3), 0.995)
    wall = (slice(*FRONT_V), slice(FRONT_U[1] + 3, FRONT_U[1] + 60), 0.96)
    assert not _firm_at(_blobs_of(_plain_frame([strip, ramp, wall]), right="surface", right_u=FRONT_U[1] + 3), u, v)
    carcass = (slice(*FRONT_V), slice(FRONT_U[1] + 3, FRONT_U[1] + 60), 1.01)  # no farther out than the front: a
    # pull's pocket cut along the door's side
    assert _firm_at(_blobs_of(_plain_frame([strip, carcass]), right="surface", right_u=FRONT_U[1] + 3), u, v)


def test_two_tabs_side_by_side_one_a_centimetre_higher_are_two_handles():
    """Two tabs 1.2 cm thick standing 3 cm out, 18 cm long, overlapping by 3 cm along their length, one 1 cm higher
    than the other (a door's tab on its bottom edge, the drawer's below on its top edge): two candidates, each where
    its tab is; a straight tab of their joint length stays one."""
    u, v = 320, 240
    left, right = (slice(v - 3, v + 4), slice(u - 100, u + 10)), (slice(v + 3, v + 10), slice(u - 10, u + 100))
    blobs = _blobs_of(_plain_frame([(*left, 0.97), (*right, 0.97)]))
    assert len(_firm_at(blobs, u - 45, v)) == 1 and len(_firm_at(blobs, u + 45, v + 6)) == 1
    (tab,) = _firm_at(blobs, u - 45, v)
    assert abs(tab.length_m - 0.18) < 0.03
    straight = _blobs_of(_plain_frame([(slice(v - 3, v + 4), slice(u - 100, u + 100), 0.97)]))
    assert len([b for b in straight if b.firm]) == 1


def test_a_knob_at_the_views_border_is_measured():
    """A knob standing out 3 cm at the rectified view's right border (the front running on to it): its surroundings
    are read within the view."""
    u, v = 522, 240
    front = (slice(*FRONT_V), slice(FRONT_U[1], 531), 1.0)
    knob = (slice(v - 8, v + 9), slice(u - 8, u + 9), 0.97)
    assert len(_firm_at(_blobs_of(_plain_frame([front, knob]), right_u=531), u, v)) == 1


def test_a_bar_on_a_front_turned_from_the_plane_stands_out_of_the_front_not_the_plane():
    """The plane found at the pointed pixel turned 2.7 degrees from the front: the front's right end stands 1.4 cm
    out of the plane (beyond the depth's noise band), its left end 1.4 cm behind. A bar standing 3 cm out of the
    front near its right end is one firm handle (before: joined to the strip of the front standing out of the plane
    there, a shape too large for a handle, and lost)."""
    frame = _plain_frame([])
    cols = np.arange(*FRONT_U)
    frame.depth_m[slice(*FRONT_V), slice(*FRONT_U)] = (1.0 - 0.014 * (cols - 320) / 150)[None, :]
    rows, bar = slice(FRONT_V[0] + 24, FRONT_V[0] + 31), slice(330, 450)
    frame.depth_m[rows, bar] -= 0.03
    bars = [b for b in _blobs_of(frame) if b.firm and b.length_m > 0.15]
    assert len(bars) == 1 and abs(bars[0].length_m - 0.2) < 0.02


def test_two_bars_joined_only_through_the_shadow_past_the_fronts_side_are_two_handles():
    """Two drawers' bars, 14 cm apart on a rectangle that merged their fronts, both lost by the D415 (seen in colour
    only) and both running on to the IR shadow past the front's left side: two handles (before: the two taken as one
    shape once the shadow was cut off, too large for a handle, and no handle at all)."""
    frame = _frame((FRONT_U[0], FRONT_U[1] - 40))
    lower = (slice(FRONT_V[0] + 110, FRONT_V[0] + 116), slice(FRONT_U[0], FRONT_U[1] - 40))
    frame.depth_m[lower], frame.color[lower] = 0.0, (128, 128, 128)
    bars = [b for b in _blobs_of(frame) if b.firm and b.inside and b.length_m > 0.35]
    assert len(bars) == 2 and abs(bars[0].centre[1] - bars[1].centre[1]) > 0.12


def test_a_bump_measured_standing_out_less_than_a_handle_is_no_handle_seen_in_colour_only():
    """A 3 x 1.7 cm bump standing 8.5 mm out of the front: a candidate (beyond the smoothed depth's noise band), but
    its points lie within one measurement's noise of the plane. It was measured, on the front's surface, not lost by
    the D415: no firm handle (before: with (almost) no points of its own, taken as seen in colour only, and firm)."""
    u, v = 320, 240
    bump = [(slice(v - 5, v + 5), slice(u - 9, u + 9), 0.9915)]
    blobs = [b for b in _blobs_of(_plain_frame(bump)) if np.linalg.norm(b.centre) < 0.03]
    assert blobs and not any(b.seen_in_colour_only for b in blobs) and not _firm_at(blobs, u, v)
