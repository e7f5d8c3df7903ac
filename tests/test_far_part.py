"""What a view keeps of a deep object: its far part, and not what its mask bled onto."""

from __future__ import annotations

import math

import numpy as np
from test_projection import bleed_mask, empty_world, perfect_observations, see

from bomc_bt.geometry import Pose2D
from bomc_bt.perception.projection import ProjectionParams, detections_to_observations, robust_centroid
from bomc_bt.world import WorldObject

POSE = Pose2D(0.0, 0.0, 0.0)


def test_a_table_seen_end_on_is_observed_at_its_middle_not_at_its_near_end():
    """Its near end is the range most of its pixels share; its top stretches 1.6 m farther in
    a tenth of them. The range cut alone kept 0.26 m of the table and put it 0.67 m short
    of its centre, past the scoring distance."""
    table = WorldObject("t", "table", (3.3, 0.0, 0.375), (1.6, 0.8, 0.75), 0.0)  # x 2.5 to 4.1
    _, [o] = perfect_observations(see([table], POSE), ["table"])
    assert abs(o.position[0] - 3.3) < 0.2 and abs(o.position[1]) < 0.05


def test_the_far_part_moves_a_views_centre_but_not_its_floor_box():
    """A box is a view's length, and the longest whole view of a category tells a part of an
    object from a whole one: grown by far parts, a chair view over the table it touches
    lengthened every chair's, and 23 chairs of an Environment-A-size floor were joined to
    their neighbours at the end of pass 2."""
    table = WorldObject("t", "table", (3.3, 0.0, 0.375), (1.6, 0.8, 0.75), 0.0)
    frame = see([table], POSE)
    _, [with_far] = perfect_observations(frame, ["table"])
    dets, _ = perfect_observations(frame, ["table"])
    [cut_only] = detections_to_observations(frame, dets, ProjectionParams(far_part=False))
    np.testing.assert_allclose(with_far.box, cut_only.box)
    assert with_far.box[2] < 2.9  # the near end the range cut kept
    assert with_far.position[0] - cut_only.position[0] > 0.4


def test_a_chair_at_a_table_does_not_take_the_table_top_its_mask_bled_onto():
    """The chair touches the table's edge, so the two are one surface in range; the chair's
    far part grows from its own pixels, not from the table top its mask spilled onto (grown
    from the spilled mask, the centre went 0.21 m onto the table, the box 0.4 m)."""
    table = WorldObject("t", "table", (3.6, 0.0, 0.375), (0.8, 1.6, 0.75), 0.0)  # x 3.2 to 4.0
    chair = WorldObject("c", "chair", (2.95, 0.3, 0.45), (0.5, 0.5, 0.9), 0.0)  # x 2.7 to 3.2, touching
    x, y = 2.4, 1.6  # looking down on the chair over its corner, the table top beyond it
    frame = see([table, chair], Pose2D(x, y, math.atan2(0.3 - y, 2.95 - x)))
    dets, _ = perfect_observations(frame, ["chair"])
    bled = bleed_mask(dets[0].mask, 0.1)
    [o] = detections_to_observations(frame, [dets[0].with_mask(bled)], ProjectionParams())
    assert o.box[2] < 3.35  # the box ends at the chair's back (3.2 m), not on the table
    assert np.linalg.norm(o.position[:2] - [2.95, 0.3]) < 0.1


def test_a_small_group_of_points_far_behind_a_view_in_two_parts_is_not_the_object():
    """A table seen end-on past the chair in front of it shows two range groups of its own;
    the 5 % of its mask that bled onto the wall 6 m off is no part of it."""
    rng = np.random.default_rng(0)
    near = rng.uniform([1.5, -0.3, 0.0], [2.0, 0.3, 0.75], size=(250, 3))  # its end before the chair
    far = rng.uniform([2.5, -0.3, 0.6], [3.3, 0.3, 0.75], size=(500, 3))  # its top past the chair
    wall = rng.uniform([6.0, -0.3, 1.0], [6.05, 0.3, 1.4], size=(40, 3))
    table = np.vstack([near, far])
    assert np.linalg.norm(robust_centroid(np.vstack([table, wall]), origin=np.zeros(3)) - table.mean(axis=0)) < 0.02


def test_a_cabinet_against_a_side_wall_keeps_off_the_wall_its_mask_bled_onto():
    """The side wall recedes from the cabinet's face without a jump in range. The range cut
    alone keeps the cabinet's near face (centre 2.22 m, 0.28 m short); its far part brings
    the centre to its middle, and what the mask spilled onto the wall does not drag it along."""
    walls, grid = empty_world()
    row, _ = grid.world_to_cell(0.0, -0.55)
    walls[int(row) - 3:int(row), :] = True  # a wall along the x axis, 0.55 m to the right
    cabinet = WorldObject("c", "cabinet", (2.5, -0.3, 0.6), (0.9, 0.5, 1.2), 0.0)  # against it
    frame = see([cabinet], Pose2D(0.0, 0.3, 0.03), walls=walls, grid=grid)
    dets, _ = perfect_observations(frame, ["cabinet"])
    bled = bleed_mask(dets[0].mask, 0.3)
    [o] = detections_to_observations(frame, [dets[0].with_mask(bled)], ProjectionParams())
    assert abs(o.position[0] - 2.5) < 0.1


def test_a_door_seen_from_close_is_marked_cut_by_the_image_top():
    door = WorldObject("d", "door", (1.6, 0.0, 1.0), (0.06, 0.9, 2.0), 0.0)
    _, [near] = perfect_observations(see([door], POSE), ["door"])
    assert near.above_image and near.position[2] < 0.8  # its lower part only
    chair = WorldObject("c", "chair", (3.0, 0.0, 0.45), (0.5, 0.5, 0.9), 0.0)
    _, [whole] = perfect_observations(see([chair], POSE), ["chair"])
    assert not whole.above_image
