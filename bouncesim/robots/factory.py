"""Build a robot by name: :func:`make_robot` (re-exported as ``bouncesim.robots.make_robot``).

The kinematic twin is always there; PyBullet (extra ``sim``), MuJoCo (extra ``mujoco``) and the
Create 2 adapter and its emulator (extra ``hardware``, pyserial) are imported only when asked
for.
"""

from __future__ import annotations

import importlib.util
import inspect
from dataclasses import replace
from typing import Any

import numpy as np

from envs import Environment, UserError

from .base import CREATE2, Robot
from .kinematic import KinematicRobot
from .noise import NoiseModel, noise_and_rng

__all__ = ["KINDS", "make_robot"]

KINDS = ("kinematic", "pybullet", "mujoco", "create2", "emulator", "create3", "create3-emulator")
"""The robots :func:`make_robot` builds."""

_EXTRAS = {"pybullet": ("pybullet", "sim"), "mujoco": ("mujoco", "mujoco"),
           "create2": ("serial", "hardware"),
           "emulator": ("serial", "hardware"), "create3": ("irobot_edu_sdk", "create3")}
_CREATE3_EMULATOR = ("start", "reflex", "slowdown", "reflex_distance", "slowdown_distance",
                     "glance_deg", "faults", "name")
_EMULATOR_OPTIONS = ("transport", "host", "port", "time_scale", "angle_bug", "faults",
                     "encoder_offset", "start", "glance_deg", "mode_offset", "lockstep", "log")


def make_robot(kind: str, env: Environment, *, noise: NoiseModel | None = None,
               rng: np.random.Generator | int | None = None, **options: Any) -> Robot:
    """A robot of ``kind`` in ``env``; every simulated body takes ``noise`` and ``rng`` the same
    way (:func:`bouncesim.robots.noise.noise_and_rng`: noise without an rng is refused).

    Parameters
    ----------
    kind : {"kinematic", "pybullet", "mujoco", "create2", "emulator", "create3", \
"create3-emulator"}
        ``kinematic``: :class:`~bouncesim.robots.kinematic.KinematicRobot`; ``pybullet``:
        :class:`~bouncesim.robots.pybullet.PyBulletRobot`; ``mujoco``:
        :class:`~bouncesim.robots.mujoco.MuJoCoRobot`; ``create2``: a real Create 2 through
        :class:`~bouncesim.robots.create2.Create2Robot` (``port`` required; it brings its own
        noise, so ``noise`` must be exact); ``emulator``: an
        :class:`~bouncesim.robots.create2.OIEmulator` of ``env`` started in this process (on a
        pty, or ``transport="tcp"``) and the Create 2 adapter connected to it through pyserial;
        closing the robot closes the emulator; ``create3``: a real Create 3 over Bluetooth
        through :class:`~bouncesim.robots.create3.Create3Robot` (``name``: the robot's
        Bluetooth name, default the first one found; it brings its own noise);
        ``create3-emulator``: the same adapter on an in-process
        :class:`~bouncesim.robots.create3.EmulatorBackend`, in lockstep (emulated time), with
        the robot's bump reflex and proximity slowdown off unless ``reflex=True`` /
        ``slowdown=True`` (our navigators assume a robot that stays at the wall).
    env : Environment
    noise : NoiseModel, optional
        Rotation noise of a simulated body (the emulator's body slip); None: exact turns.
    rng : numpy.random.Generator or int, optional
        Draws the noise (an int is a seed).
    **options
        Keyword arguments of the body's constructor. ``create2`` and ``emulator`` also take
        ``wheel_base`` [m] (the effective wheel base used to time or measure turns, in
        [0.1, 0.5]); ``emulator`` splits its options between the emulator (``transport``,
        ``time_scale``, ``faults`` as :class:`~bouncesim.robots.create2.Fault` or
        ``"KIND@S"`` strings, ``lockstep``, ...) and the adapter (``mode``, ``turn``,
        ``sensing``, ...; ``time_scale`` goes to both).

    Raises
    ------
    UserError
        One sentence: an unknown kind or option, a missing extra (naming it), a bad value.

    Examples
    --------
    >>> import envs
    >>> bot = make_robot("kinematic", envs.load("lab"), glance_deg=80)
    >>> type(bot).__name__, bot.glance_deg
    ('KinematicRobot', 80.0)
    >>> make_robot("roomba", envs.load("lab"))
    Traceback (most recent call last):
    ...
    envs.errors.UserError: unknown robot 'roomba'; use kinematic, pybullet, mujoco, create2,
    emulator, create3 or create3-emulator.
    """
    if kind not in KINDS:
        raise UserError(f"unknown robot {kind!r}; use {', '.join(KINDS[:-1])} or {KINDS[-1]}.")
    if kind in _EXTRAS:
        module, extra = _EXTRAS[kind]
        if importlib.util.find_spec(module) is None:
            raise UserError(f"the {kind} robot needs the {extra} extra ({module} is missing): "
                            f"pip install 'bouncesim[{extra}]'.")
    if kind == "kinematic":
        _check_options(kind, KinematicRobot, options)
        return KinematicRobot(env, noise, rng, **options)
    if kind == "pybullet":
        from .pybullet import PyBulletRobot
        _check_options(kind, PyBulletRobot, options)
        return PyBulletRobot(env, noise, rng, **options)
    if kind == "mujoco":
        from .mujoco import MuJoCoRobot
        _check_options(kind, MuJoCoRobot, options)
        return MuJoCoRobot(env, noise, rng, **options)
    if kind in ("create3", "create3-emulator"):
        return _create3(kind, env, noise, rng, options)
    from .create2 import Create2Robot, OIEmulator, parse_fault
    options = dict(options)
    wheel_base = options.pop("wheel_base", None)
    if wheel_base is not None:
        if not 0.1 <= float(wheel_base) <= 0.5:
            raise UserError(f"the wheel base must lie in [0.1, 0.5] m, got {wheel_base:g}.")
        options["spec"] = replace(options.get("spec") or CREATE2, wheel_base=float(wheel_base))
    if kind == "create2":
        noise, _ = noise_and_rng(noise, rng)
        if not getattr(noise, "exact", False):
            raise UserError("rotation noise is for simulated robots; a real Create 2 brings "
                            "its own.")
        port = options.pop("port", None)
        if not port:
            raise UserError("the create2 robot needs a serial port (port='/dev/ttyUSB0', "
                            "COM3 or a pyserial URL).")
        _check_options(kind, Create2Robot, options)
        bot = Create2Robot(port, **options)
        bot.env = env                       # the room the user says the robot is in
        return bot
    emu_options = {k: options.pop(k) for k in _EMULATOR_OPTIONS if k in options}
    if "time_scale" in emu_options:
        options["time_scale"] = emu_options["time_scale"]
    emu_options["faults"] = [f if not isinstance(f, str) else parse_fault(f)
                             for f in emu_options.get("faults", ())]
    for name in ("emulator", "own_emulator"):
        if name in options:
            raise UserError(f"the emulator robot builds its own emulator; drop {name}=.")
    _check_options(kind, Create2Robot, options)
    emu = OIEmulator(env, noise, rng, **emu_options).start()
    try:
        bot = Create2Robot(emu.url, emulator=emu, own_emulator=True, **options)
    except BaseException:
        emu.close()
        raise
    bot.env = env
    return bot


def _check_options(kind: str, cls, options: dict) -> None:
    """Refuse, in one sentence, an option the body's constructor does not take."""
    params = inspect.signature(cls).parameters
    names = [n for n, p in params.items() if p.kind is p.KEYWORD_ONLY]
    unknown = sorted(set(options) - set(names))
    if unknown:
        raise UserError(f"the {kind} robot takes no option {unknown[0]!r}; it takes "
                        f"{', '.join(names)}.")


def _create3(kind: str, env: Environment, noise, rng, options: dict) -> Robot:
    """The Create 3 adapter on Bluetooth (``create3``) or on the in-process emulator."""
    from .create3 import Create3Robot, EmulatorBackend
    options = dict(options)
    if kind == "create3":
        noise, _ = noise_and_rng(noise, rng)
        if not getattr(noise, "exact", False):
            raise UserError("rotation noise is for simulated robots; a real Create 3 brings "
                            "its own.")
        name = options.pop("name", None)
        _check_options(kind, Create3Robot, options)
        from irobot_edu_sdk.backend.bluetooth import Bluetooth
        bot = Create3Robot(Bluetooth(name), **options)
        bot.env = env
        return bot
    emu = {k: options.pop(k) for k in _CREATE3_EMULATOR if k in options}
    emu.setdefault("reflex", False)
    emu.setdefault("slowdown", False)
    _check_options(kind, Create3Robot, options)
    backend = EmulatorBackend(env, noise=noise, rng=rng, time="lockstep", **emu)
    bot = Create3Robot(backend, **options)
    bot.env = env
    return bot
