"""The Create 2 bumper of a PyBullet body, read from its contact points with the walls.

The bumper is the front arc of the disk: a contact point with a wall that touches it (within
``BUMPER_REACH``, 0.1 mm) whose bearing from the heading lies within ± the arc closes the
switch on its side (left for bearings ≥ −10°, right for ≤ 10°, so contacts within ±10° of
straight ahead close both).
"""

from __future__ import annotations

import math

from envs.motion import CENTRE_ZONE_DEG
from planners.measures import wrap180

__all__ = ["BUMPER_REACH", "CONTACT_TOLERANCE", "BUMP_CENTRE_DEG", "contact_bearing", "read_bumper"]

BUMPER_REACH = 1e-4
"""[m] The bumper closes on a wall contact at most this far from the body: a touch (a pressing
contact reads −0.01 to −0.02 mm) with 0.1 mm of slack, not PyBullet's early contacts up to
1 mm before the touch. A bumper closes under force; reading walls 1 mm away made a body
sliding toward a side's end bump on the next wall slab's corner 18 mm before it got there
(docs/model.md Appendix B). (MuJoCo's contacts push from 1 mm, so its body reads 1 mm.)"""

CONTACT_TOLERANCE = 1e-3
"""[m] :meth:`PyBulletRobot.wall_contacts` reports contact points within this distance (the
calibration's first contact); the bumper closes only within ``BUMPER_REACH``."""
BUMP_CENTRE_DEG = CENTRE_ZONE_DEG
"""Contacts within ± this angle [deg] of straight ahead close both switches."""


def contact_bearing(pos, x: float, y: float, yaw_deg: float) -> float:
    """Bearing [deg] in (−180, 180] of the point ``pos`` seen from (x, y) heading ``yaw_deg``."""
    return wrap180(math.degrees(math.atan2(pos[1] - y, pos[0] - x)) - yaw_deg)


def read_bumper(p, body: int, wall_set: frozenset, arc_deg: float, kw: dict,
                contacts=None) -> tuple[bool, bool]:
    """(left, right) bumper of body ``body``: its wall contacts (within ``BUMPER_REACH``, bearing
    within ± ``arc_deg`` [deg]; within ±10° both sides close). ``contacts``: the body's
    contact points if already read.
    """
    if contacts is None:
        contacts = p.getContactPoints(bodyA=body, linkIndexA=-1, **kw)
    if not contacts:
        return False, False
    (x, y, _), orn = p.getBasePositionAndOrientation(body, **kw)
    yaw = math.degrees(p.getEulerFromQuaternion(orn)[2])
    left = right = False
    for c in contacts:
        if c[2] not in wall_set or c[8] > BUMPER_REACH:
            continue
        rel = contact_bearing(c[5], x, y, yaw)
        if abs(rel) > arc_deg:
            continue
        if rel >= -BUMP_CENTRE_DEG:
            left = True
        if rel <= BUMP_CENTRE_DEG:
            right = True
    return left, right
