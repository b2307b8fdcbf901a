"""Doctest collection over envs, planners and bouncesim (``--doctest-modules``).

Every module imports without the optional extras (pybullet, pyserial are imported where they
are used), but some examples run a backend: when its extra is not installed, those modules'
examples are not collected, for the reason given next to each.
"""

from __future__ import annotations

import importlib.util

collect_ignore: list[str] = []

if importlib.util.find_spec("serial") is None:
    # the Create 2 examples talk to the emulator through a pyserial link (extra "hardware")
    collect_ignore += ["bouncesim/robots/create2/adapter.py",
                       "bouncesim/robots/create2/emulator.py"]
if importlib.util.find_spec("gymnasium") is None:
    # the Gymnasium environment needs its extra (gym)
    collect_ignore += ["bouncesim/gym.py"]
if importlib.util.find_spec("pettingzoo") is None:
    # the team environments need their extra (team)
    collect_ignore += ["bouncesim/team.py"]
if importlib.util.find_spec("mujoco") is None:
    # the MuJoCo Create 2's examples build a MuJoCo world (extra mujoco)
    collect_ignore += ["bouncesim/robots/mujoco/robot.py", "bouncesim/robots/mujoco/batch.py"]
