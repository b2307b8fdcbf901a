"""The MuJoCo world of an environment: walls, floor and Create 2 bodies written as MJCF.

:func:`world_xml` returns the MJCF text of a room (docs/model.md §1 frame: x east, y north,
metres) with ``n_robots`` Create 2 bodies in it. The walls are the convex pieces the PyBullet
world is built from (:mod:`bouncesim.robots.wall_pieces`: one slab per boundary edge, the
obstacles cut into convex parts), each extruded to a 0.2 m prism (a MuJoCo mesh, which MuJoCo
collides as its convex hull, so a convex piece is exact).

A body (:func:`robot_xml`) is the Create 2 of the PyBullet world built with MuJoCo's own
parts: a free-floating base (a 0.09 m high cylinder, its underside 0.01 m above the floor, the
centre of mass over the axle), two driven wheels (spheres of the wheel diameter on hinge
joints 0.235 m apart, velocity actuators with a torque limit, friction 1 against the floor)
and a frictionless front caster and rear skid hanging 1 mm above the floor.

Collision filtering: robot geoms have ``contype`` 2 and ``conaffinity`` 1, the floor and the
walls ``contype`` 1 and ``conaffinity`` 2, so a robot meets the floor and the walls, and
never another robot (MuJoCo collides two geoms when ``contype`` of one shares a bit with
``conaffinity`` of the other): robots in one world ignore each other.

Contacts: the walls and the casters are frictionless (``condim`` 1 and a higher
``priority``, so their setting wins over the other geom's). The body detects a wall within
``margin`` (1 mm), meant to push only once they overlap (``gap`` = ``margin``). Measured
(MuJoCo 4.0, ``mj_contactForce``): contacts that push the body read 0.1–0.95 mm, so the
bumper's 1 mm is the touch here, not an early reading (docs/model.md Appendix B).

>>> import envs
>>> xml = world_xml(envs.load("lab"), 2)
>>> xml.count('<joint type="free"'), xml.count("<velocity ")
(2, 4)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry.polygon import orient

from envs import Environment

from ..base import RobotSpec
from ..wall_pieces import WALL_THICKNESS, convex_pieces, wall_pieces

__all__ = ["BodyParams", "robot_xml", "world_xml", "WALL_HEIGHT"]

WALL_HEIGHT = 0.2          # [m]
BODY_HEIGHT = 0.09         # [m]
BODY_CLEARANCE = 0.01      # floor to the underside of the body [m]
WHEEL_MASS = 0.1           # each [kg]
CASTER_RADIUS = 0.01       # [m]
CASTER_OFFSET = 0.13       # caster / skid ahead of / behind the axle [m]
CASTER_GAP = 0.001         # casters hang this far above the floor at rest [m]
CONTACT_MARGIN = 1e-3      # a wall within this distance is a contact [m]
WHEEL_SOLREF = "0.01 1"    # stiffer than MuJoCo's default 0.02 s: the wheels sink 0.12 mm, not
WHEEL_SOLIMP = "0.99 0.999 0.001"   # 0.35 mm, into the floor (rolling radius -0.3 %, not -1 %)


@dataclass(frozen=True)
class BodyParams:
    """Physics settings of one MuJoCo Create 2 (see :class:`~.robot.MuJoCoRobot`).

    Attributes
    ----------
    body_radius : float      collision radius of the body [m]
    wheel_torque : float     torque limit of each wheel's velocity actuator [N m]
    wheel_gain : float       velocity gain kv of the wheel actuators [N m s/rad]
    wheel_friction : float   wheel–floor sliding friction coefficient
    wheel_armature : float   reflected rotor inertia of each wheel's gear motor [kg m²]
    """

    body_radius: float = 0.168
    wheel_torque: float = 2.0
    wheel_gain: float = 2.0
    wheel_friction: float = 1.0
    wheel_armature: float = 0.005


def _f(v) -> str:
    return " ".join(f"{float(x):.9g}" for x in np.ravel(v))


def robot_xml(i: int, spec: RobotSpec, params: BodyParams, x: float = 0.0,
              y: float = 0.0) -> tuple[str, str]:
    """(body MJCF, actuator MJCF) of robot ``i``: names ``r{i}``, ``r{i}_body``,
    ``r{i}_left`` / ``r{i}_right`` (wheel joints and their actuators, left = +y).
    """
    R = spec.wheel_diameter / 2
    half = spec.wheel_base / 2
    body_z = BODY_CLEARANCE + BODY_HEIGHT / 2 - R
    caster_z = CASTER_RADIUS + CASTER_GAP - R
    base_mass = spec.mass - 2 * WHEEL_MASS
    rb = params.body_radius
    ixx = base_mass * (3 * rb ** 2 + BODY_HEIGHT ** 2) / 12
    izz = base_mass * rb ** 2 / 2
    n = f"r{i}"
    filt = 'contype="2" conaffinity="1"'
    wheel_i = 0.4 * WHEEL_MASS * R * R
    wheels = "".join(f"""
      <body name="{n}_{side[0]}w" pos="{_f([0, sign * half, 0])}">
        <joint name="{n}_{side}" type="hinge" axis="0 1 0"
               armature="{params.wheel_armature:.9g}"/>
        <inertial pos="0 0 0" mass="{WHEEL_MASS}" diaginertia="{_f([wheel_i] * 3)}"/>
        <geom type="sphere" size="{R:.9g}" {filt} condim="3" mass="0" solref="{WHEEL_SOLREF}"
              solimp="{WHEEL_SOLIMP}" friction="{params.wheel_friction:.9g} 0 0"/>
      </body>""" for side, sign in (("left", 1), ("right", -1)))
    body = f"""
    <body name="{n}" pos="{_f([x, y, R])}">
      <joint type="free" name="{n}_free"/>
      <inertial pos="0 0 0" mass="{base_mass:.9g}" diaginertia="{_f([ixx, ixx, izz])}"/>
      <geom name="{n}_body" type="cylinder" size="{_f([rb, BODY_HEIGHT / 2])}"
            pos="{_f([0, 0, body_z])}" {filt} margin="{CONTACT_MARGIN}"
            gap="{CONTACT_MARGIN}" condim="1" rgba="0.25 0.45 0.85 1" mass="0"/>
      <geom name="{n}_caster" type="sphere" size="{CASTER_RADIUS}"
            pos="{_f([CASTER_OFFSET, 0, caster_z])}" {filt} condim="1" priority="1"
            mass="0"/>
      <geom name="{n}_skid" type="sphere" size="{CASTER_RADIUS}"
            pos="{_f([-CASTER_OFFSET, 0, caster_z])}" {filt} condim="1" priority="1"
            mass="0"/>
{wheels}
    </body>"""
    lim = f'forcelimited="true" forcerange="{_f([-params.wheel_torque, params.wheel_torque])}"'
    act = (f'    <velocity name="{n}_left" joint="{n}_left" kv="{params.wheel_gain:.9g}" '
           f'{lim}/>\n'
           f'    <velocity name="{n}_right" joint="{n}_right" kv="{params.wheel_gain:.9g}" '
           f'{lim}/>\n')
    return body, act


def _prism(name: str, piece) -> tuple[str, str]:
    """(mesh asset, geom) of a convex polygon extruded from the floor to the wall height."""
    ring = np.asarray(orient(piece, 1.0).exterior.coords)[:-1]
    verts = [(x, y, z) for z in (0.0, WALL_HEIGHT) for x, y in ring]
    return (f'    <mesh name="{name}" vertex="{_f(verts)}"/>\n',
            f'    <geom name="{name}" type="mesh" mesh="{name}" contype="1" conaffinity="2" '
            f'condim="1" priority="2" rgba="0.45 0.42 0.40 1"/>\n')


def world_xml(env: Environment, n_robots: int = 1, *, spec: RobotSpec | None = None,
              params: BodyParams | None = None, time_step: float = 0.005,
              solver_iterations: int = 50, cone: str = "elliptic") -> str:
    """MJCF text of ``env`` with ``n_robots`` Create 2 bodies (all at the origin, to be
    placed); geoms ``wall{k}`` are the walls, ``floor`` the floor. ``cone``: MuJoCo's
    friction cone, ``"elliptic"`` (Coulomb's isotropic cone) or ``"pyramidal"`` (MuJoCo's
    default, a four-sided approximation whose lateral slip depends on the direction).
    """
    from ..base import CREATE2
    spec = spec if spec is not None else CREATE2
    params = params if params is not None else BodyParams()
    pieces = list(wall_pieces(env.boundary, WALL_THICKNESS))
    pieces += [pc for ob in env.obstacles for pc in convex_pieces(ob)]
    assets, geoms = [], []
    for k, pc in enumerate(pieces):
        a, g = _prism(f"wall{k}", pc)
        assets.append(a)
        geoms.append(g)
    x0, y0, x1, y1 = env.bounds
    bodies, acts = [], []
    for i in range(n_robots):
        b, a = robot_xml(i, spec, params, (x0 + x1) / 2, (y0 + y1) / 2)
        bodies.append(b)
        acts.append(a)
    size = max(x1 - x0, y1 - y0) + 1.0
    return f"""<mujoco model="bouncesim-{env.name}">
  <option timestep="{time_step:.9g}" integrator="implicitfast" iterations="{solver_iterations}"
          cone="{cone}" gravity="0 0 -9.81"/>
  <asset>
{''.join(assets)}  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="{_f([size, size, 0.1])}"
          pos="{_f([(x0 + x1) / 2, (y0 + y1) / 2, 0])}" contype="1" conaffinity="2"
          condim="3" friction="1 0 0" rgba="0.93 0.93 0.88 1"/>
{''.join(geoms)}{''.join(bodies)}
  </worldbody>
  <actuator>
{''.join(acts)}  </actuator>
</mujoco>
"""
