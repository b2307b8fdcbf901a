"""The Create 2 bumper of a PyBullet body, read from its contacts with the walls.

The bumper is the front arc of the disk: a wall contact that presses the body (its distance
at most ``BUMPER_REACH``, 0: a touch or a penetration) whose bearing from the heading lies
within ± the arc closes the switch on its side (left for bearings ≥ −10°, right for ≤ 10°,
so contacts within ±10° of straight ahead close both). The bearing is the contact normal's
(the direction of the push, the disk's exact contact bearing), not the witness point's: the
body pitches by up to 0.44° while it drives, and the witness point on the cylinder's rim
moves with the pitch, so a bearing read from it depended on whether the body was driving or
at rest (docs/model.md Appendix B).
"""

from __future__ import annotations

import math

from envs.motion import CENTRE_ZONE_DEG
from planners.measures import wrap180

__all__ = ["BUMPER_REACH", "CONTACT_TOLERANCE", "BUMP_CENTRE_DEG", "normal_bearing",
           "read_bumper"]

BUMPER_REACH = 0.0
"""[m] The bumper closes on a wall contact at most this far from the body: a touch or a
penetration (a pressing contact reads −0.01 to −0.05 mm). A bumper closes under force.
PyBullet also reports walls up to 1 mm before the touch, and, where two wall slabs meet in
one plane, the next slab's corner a few mm ahead of the contact, 0.01–0.06 mm away at a
bearing up to 2° further forward: with a reach of 1 mm a body sliding toward a side's end
bumped on the next slab 18 mm before it got there, with 0.1 mm it still bumped on the
corner of a reflex corner's slab when it slid at 8.5°–10.4° (docs/model.md Appendix B).
(MuJoCo's contacts push from 1 mm, so its body reads 1 mm.)"""

CONTACT_TOLERANCE = 1e-3
"""[m] :meth:`PyBulletRobot.wall_contacts` reports contact points within this distance (the
calibration's first contact); the bumper closes only within ``BUMPER_REACH``."""
BUMP_CENTRE_DEG = CENTRE_ZONE_DEG
"""Contacts within ± this angle [deg] of straight ahead close both switches."""


def normal_bearing(normal_on_wall, yaw_deg: float) -> float:
    """Bearing [deg] in (−180, 180] from the heading ``yaw_deg`` of a contact whose normal on
    the wall is ``normal_on_wall`` (pointing from the wall to the body): the direction of the
    push, −normal.

    >>> normal_bearing((-1.0, 0.0, 0.0), 30.0), round(normal_bearing((0.0, 1.0, 0.0), 10.0), 6)
    (-30.0, -100.0)
    """
    return wrap180(math.degrees(math.atan2(-normal_on_wall[1], -normal_on_wall[0])) - yaw_deg)


def read_bumper(p, body: int, wall_set: frozenset, arc_deg: float, kw: dict,
                contacts=None) -> tuple[bool, bool]:
    """(left, right) bumper of body ``body``: its wall contacts (within ``BUMPER_REACH``, the
    normal's bearing within ± ``arc_deg`` [deg]; within ±10° both sides close).
    ``contacts``: the body's contact points if already read.
    """
    if contacts is None:
        contacts = p.getContactPoints(bodyA=body, linkIndexA=-1, **kw)
    if not contacts:
        return False, False
    _, orn = p.getBasePositionAndOrientation(body, **kw)
    yaw = math.degrees(p.getEulerFromQuaternion(orn)[2])
    left = right = False
    for c in contacts:
        if c[2] not in wall_set or c[8] > BUMPER_REACH:
            continue
        rel = normal_bearing(c[7], yaw)
        if abs(rel) > arc_deg:
            continue
        if rel >= -BUMP_CENTRE_DEG:
            left = True
        if rel <= BUMP_CENTRE_DEG:
            right = True
    return left, right
