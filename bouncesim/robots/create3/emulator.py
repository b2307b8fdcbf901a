"""A Create 3 the iRobot Python SDK talks to: :class:`EmulatorBackend`, an SDK ``Backend``
whose robot moves in a bouncesim environment.

``Create3(EmulatorBackend(envs.load("lab"), start=(0.51, 0.51, 0)))`` runs an unmodified
``irobot-edu-sdk`` script against the emulator; ``Create3(Bluetooth())`` runs the same script
on the robot. :class:`Create3Emulator` is the robot itself (no asyncio): packets in, packets
out, the body moved in emulated time by :class:`bouncesim.robots.wheel_body.WheelBody` (the
kinematic twin, as the Create 2 emulator's).

What it answers (device, command; docs/readme_create3.md has the table):

- motion: wheel speeds (1, 4), left / right speed (1, 6 / 7), capped at 306 mm/s; move
  (1, 8) at 0.2 m/s and turn (1, 12) at 90°/s, each answered with the pose when done (or
  when a bump or a stop ends it); reset navigation (1, 15); get position (1, 16); stop (0, 3);
- robot: versions (0, 0), set / get name (0, 1 / 2), disconnect (0, 6), event enables
  (0, 7 / 9 / 11), serial number (0, 14), SKU (0, 15), battery (14, 1), lights (3, 2),
  notes (5, 0) and speech (5, 4), accelerometer (16, 1), IR proximity (11, 1 / 2, all far),
  IPv4 addresses (100, 1);
- events: bump (12, 0) on every change of the bumper (a uint32 timestamp [ms], then 0x80
  left, 0x40 right), motor stall (1, 29), battery (14, 0) once at connection.

Poses are the robot's odometry frame, as ``get_position`` reports it: x, y [cm] from where the
robot started or last reset its navigation, heading [deg] 90 there and counter-clockwise
positive, in (−180, 180]. The emulated robot's odometry is exact (its heading is the IMU's:
spin slip shows in it).

The robot's own behaviour (options; on by default, as the robot ships):

- ``reflex``: on a bump the robot drops its wheel command and backs off ``reflex_distance``
  (2 cm) at 0.1 m/s; commands that arrive meanwhile start when it is done (Create 3's bump
  reflex);
- ``slowdown``: closer than ``slowdown_distance`` (0.15 m) to a wall ahead, forward speed is
  capped at 0.1 m/s (its proximity slowdown).
The distances and speeds are our assumptions: iRobot documents the behaviours, not the
figures.

Faults (``faults=["KIND@S", ...]``, emulated seconds after connection): ``disconnect`` (the
link drops; the robot stops), ``drop-response`` (the next answer is lost), ``stall-left`` /
``stall-right`` (that wheel stops; a stall event is sent), ``garbage`` (a packet that fails its
CRC), ``no-connect`` (at 0: the robot never accepts the connection).
"""

from __future__ import annotations

import asyncio
import functools
import heapq
import itertools
import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from envs import Environment, UserError

from ..create2.faults import Fault, parse_fault
from ..noise import NoiseModel
from ..wheel_body import WheelBody
from .clock import VirtualTimeLoop
from .packets import MAX_SPEED_MM_S, Packet

__all__ = ["Create3Emulator", "Create3Fault", "EmulatorBackend", "FAULT_KINDS"]

FAULT_KINDS = ("disconnect", "drop-response", "stall-left", "stall-right", "garbage",
               "no-connect")
PERIOD = 0.015                  # [s] the emulator's motion tick
MOVE_SPEED_MM_S = 200           # move (1, 8)
TURN_DEG_S = 90.0               # turn (1, 12)
REFLEX_SPEED_MM_S = 100
SLOW_SPEED_MM_S = 100
FIRMWARE = (0, 1, 2, 3, 0, 1, 0, 1, 5, 0)   # get_versions' 10 bytes (protocol 1.5)


@dataclass(frozen=True)
class Create3Fault(Fault):
    """A Create 3 fault that strikes ``at`` [s] of emulated time after connection."""

    KINDS: ClassVar[tuple] = FAULT_KINDS


def _wrap180(deg: float) -> float:
    """Heading in (−180, 180]."""
    h = math.fmod(deg, 360.0)
    if h <= -180.0:
        h += 360.0
    elif h > 180.0:
        h -= 360.0
    return h


class Create3Emulator:
    """The emulated Create 3: packets in (:meth:`receive`), packets out (:meth:`due`), the body
    moved by :meth:`advance`; all at emulated times [s] the caller gives.
    """

    def __init__(self, env: Environment, *, start=None, noise: NoiseModel | None = None,
                 rng: np.random.Generator | int | None = None, reflex: bool = True,
                 slowdown: bool = True, reflex_distance: float = 0.02,
                 slowdown_distance: float = 0.15, glance_deg: float | None = 80.0,
                 faults: Iterable = (), name: str = "bouncesim-create3") -> None:
        self.body = WheelBody(env, noise, rng, start=start, glance_deg=glance_deg)
        self.spec = self.body.spec
        self.reflex, self.slowdown = bool(reflex), bool(slowdown)
        self.reflex_distance = float(reflex_distance)
        self.slowdown_distance = float(slowdown_distance)
        self.name = str(name)
        self.faults = sorted((f if isinstance(f, Fault) else parse_fault(f, Create3Fault)
                              for f in faults), key=lambda f: f.at)
        self.connected = False
        self.t_connect = 0.0
        self._out: list = []                 # heap of (due [s], seq, bytes)
        self._seq = itertools.count()
        self._cmd = (0.0, 0.0)               # the wheel command [mm/s] (left, right)
        self._task = None                    # (kind, inc, end time [s]) of a move / turn
        self._reflex_until = None
        self._bumper = (False, False)
        self._drop_next = False
        self._odom = self.body.true_pose()
        self._enabled = bytearray(b"\xff" * 16)
        self.log: list[str] = []

    # ------------------------------------------------------------------ frames and packets
    def odometry(self) -> tuple[float, float, float]:
        """(x [cm], y [cm], heading [deg]) as the robot reports it."""
        x0, y0, h0 = self._odom
        x, y, h = self.body.true_pose()
        a = math.radians(90.0 - h0)
        dx, dy = x - x0, y - y0
        rx = dx * math.cos(a) - dy * math.sin(a)
        ry = dx * math.sin(a) + dy * math.cos(a)
        return rx * 100.0, ry * 100.0, _wrap180(h - h0 + 90.0)

    def _stamp(self, now: float) -> bytes:
        return struct.pack(">I", int(round(max(now - self.t_connect, 0.0) * 1000)) & 0xFFFFFFFF)

    def _pose_payload(self, now: float) -> bytes:
        x, y, h = self.odometry()
        return self._stamp(now) + struct.pack(">iih", int(round(x * 10)), int(round(y * 10)),
                                              int(round(h * 10)))

    def _send(self, packet: Packet, due: float, answer: bool = False) -> None:
        if answer and self._drop_next:
            self._drop_next = False
            self.log.append(f"{due:.3f} s: dropped the answer to {packet.device}/"
                            f"{packet.command}")
            return
        if not answer and packet.device < 128 and \
                not self._enabled[packet.device // 8] & (0x80 >> packet.device % 8):
            return
        heapq.heappush(self._out, (due, next(self._seq), packet.to_bytes()))

    def due(self, now: float) -> list[bytes]:
        """Packets the robot has sent by ``now``."""
        out = []
        while self._out and self._out[0][0] <= now + 1e-12:
            out.append(heapq.heappop(self._out)[2])
        return out

    # ------------------------------------------------------------------ life cycle
    def connect(self, now: float) -> bool:
        """Accept a connection at ``now`` (False: the robot never answers)."""
        if self.faults and self.faults[0].kind == "no-connect":
            return False
        self.connected, self.t_connect = True, now
        self.body.t = max(self.body.t, now)
        self._send(Packet(14, 0, 0, self._stamp(now) + struct.pack(">HB", 14_400, 87)), now)
        return True

    def place(self, x: float, y: float, heading_deg: float, now: float) -> None:
        """A person puts the robot down at a pose at ``now`` (its odometry does not see it)."""
        self.advance(now)
        self.body.place(x, y, heading_deg)
        self._check_bumper(now)

    def disconnect(self, now: float) -> None:
        """The link is gone: the robot stops."""
        self.advance(now)
        self.connected = False
        self._set_wheels(0.0, 0.0)
        self._task = None

    # ------------------------------------------------------------------ time
    def next_wake(self, now: float) -> float | None:
        """When :meth:`advance` must run next: the next tick while moving, the next fault or
        queued packet; None when nothing will happen.
        """
        times = []
        if self._out:
            times.append(self._out[0][0])
        if self.faults and self.connected:
            times.append(self.t_connect + self.faults[0].at)
        if self._moving():
            tick = now + PERIOD
            vl, vr = self.body.actual_wheels()
            free = self.body.free_ahead()
            if vl == vr and vl > 0 and not self.body.lifted and free > 1e-6:
                tick = min(tick, now + free / vl)       # straight: wake at the contact
            times.append(tick)
        if self._task is not None:
            times.append(self._task[2])
        if self._reflex_until is not None:
            times.append(self._reflex_until)
        return min(times) if times else None

    def _moving(self) -> bool:
        return self.body.left != 0 or self.body.right != 0

    def advance(self, now: float) -> None:
        """Move the robot up to ``now``: ticks of at most :data:`PERIOD`, faults, bumps, the
        reflex, the slowdown and the end of a move or turn.
        """
        while self.body.t < now - 1e-12:
            t = min(now, self.body.t + PERIOD)
            if self.faults and self.connected and \
                    self.t_connect + self.faults[0].at <= t:
                t = max(self.body.t, self.t_connect + self.faults[0].at)
            if self._task is not None:
                t = min(t, max(self.body.t, self._task[2]))
            if self._reflex_until is not None:
                t = min(t, max(self.body.t, self._reflex_until))
            self._limit_speed()
            contact = self.body.advance_to(t)
            at = contact if contact is not None else t
            self._check_bumper(at)
            self._check_task(t)
            self._strike_due(t)
        self._strike_due(now)

    def _limit_speed(self) -> None:
        left, right = self._cmd
        if self._reflex_until is not None:
            return
        if self.slowdown and left > 0 and right > 0 and \
                self.body.free_ahead() < self.slowdown_distance:
            k = min(1.0, SLOW_SPEED_MM_S / max(left, right))
            self.body.set_wheels(left * k, right * k)
        else:
            self.body.set_wheels(left, right)

    def _set_wheels(self, left: float, right: float) -> None:
        def cap(v):
            return max(-MAX_SPEED_MM_S, min(MAX_SPEED_MM_S, float(v)))
        self._cmd = (cap(left), cap(right))
        if self._reflex_until is None:
            self.body.set_wheels(*self._cmd)

    def _free_at(self, now: float) -> float:
        """When the wheels obey commands again: now, or the end of a running reflex."""
        return now if self._reflex_until is None else max(now, self._reflex_until)

    def _check_bumper(self, now: float) -> None:
        state = self.body.bumper()
        if state == self._bumper:
            return
        pressed = (state[0] or state[1]) and not (self._bumper[0] or self._bumper[1])
        self._bumper = state
        bits = (0x80 if state[0] else 0) | (0x40 if state[1] else 0)
        self._send(Packet(12, 0, 0, self._stamp(now) + bytes([bits])), now)
        if pressed:
            if self._task is not None and self._task[0] == "move":
                self._finish_task(now)
            if self.reflex and self._reflex_until is None:
                start = max(now, self.body.t)       # (a contact mid-tick: from the tick's end)
                self._reflex_until = start + self.reflex_distance / (REFLEX_SPEED_MM_S / 1000)
                self._cmd = (0.0, 0.0)
                self.body.set_wheels(-REFLEX_SPEED_MM_S, -REFLEX_SPEED_MM_S)

    def _check_task(self, now: float) -> None:
        if self._reflex_until is not None and now >= self._reflex_until - 1e-12:
            self._reflex_until = None
            self.body.set_wheels(*self._cmd)        # what was commanded meanwhile
        task = self._task
        if task is None:
            return
        if now >= task[2] - 1e-12:
            self._finish_task(now)

    def _finish_task(self, now: float) -> None:
        kind, inc, _ = self._task
        self._task = None
        self._set_wheels(0.0, 0.0)
        self.body.end_spin()
        self._send(Packet(1, 8 if kind == "move" else 12, inc, self._pose_payload(now)), now,
                   answer=True)

    def _strike_due(self, now: float) -> None:
        while self.faults and self.connected and self.t_connect + self.faults[0].at <= now:
            kind = self.faults.pop(0).kind
            self.log.append(f"{now:.3f} s: fault {kind}")
            if kind == "disconnect":
                self.disconnect(now)
            elif kind == "drop-response":
                self._drop_next = True
            elif kind in ("stall-left", "stall-right"):
                side = kind.split("-")[1]
                self.body.stalled[side] = True
                self._send(Packet(1, 29, 0, self._stamp(now) + bytes([side == "right", 1])),
                           now)
            elif kind == "garbage":
                raw = bytearray(Packet(12, 0, 0, self._stamp(now) + b"\xc0").to_bytes())
                raw[-1] ^= 0x5A
                heapq.heappush(self._out, (now, next(self._seq), bytes(raw)))

    # ------------------------------------------------------------------ commands
    def receive(self, raw: bytes, now: float) -> None:
        """Obey one 20-byte packet written at ``now`` (bad CRC or unknown: ignored)."""
        if not self.connected:
            return
        try:
            p = Packet.from_bytes(raw)
        except UserError:
            return
        self.advance(now)
        dev, cmd, inc, pl = p.device, p.command, p.inc, p.payload

        def answer(payload: bytes = b"", at: float = now) -> None:
            self._send(Packet(dev, cmd, inc, payload), at, answer=True)

        if (dev, cmd) == (1, 4):
            self._task = None
            self._set_wheels(*struct.unpack(">ii", pl[:8]))
        elif (dev, cmd) in ((1, 6), (1, 7)):
            (v,) = struct.unpack(">i", pl[:4])
            left, right = self._cmd
            self._set_wheels(v, right) if cmd == 6 else self._set_wheels(left, v)
        elif (dev, cmd) == (1, 8):
            (mm,) = struct.unpack(">i", pl[:4])
            self._task = ("move", inc, self._free_at(now) + abs(mm) / MOVE_SPEED_MM_S)
            s = MOVE_SPEED_MM_S if mm >= 0 else -MOVE_SPEED_MM_S
            self._set_wheels(s, s)
            if mm == 0:
                self._finish_task(now)
        elif (dev, cmd) == (1, 12):
            (dd,) = struct.unpack(">i", pl[:4])
            deg = -dd / 10.0                                    # positive clockwise
            self.body.end_spin()
            w = self.spec.wheel_base / 2 * math.radians(TURN_DEG_S) * 1000
            self._task = ("turn", inc, self._free_at(now) + abs(deg) / TURN_DEG_S)
            self._set_wheels(-w, w) if deg > 0 else self._set_wheels(w, -w)
            if deg == 0:
                self._finish_task(now)
        elif (dev, cmd) == (1, 15):
            self._odom = self.body.true_pose()
        elif (dev, cmd) == (1, 16):
            answer(self._pose_payload(now))
        elif (dev, cmd) == (0, 3):
            self._task = None
            self._set_wheels(0.0, 0.0)
            self.body.end_spin()
        elif (dev, cmd) == (0, 6):
            self.disconnect(now)
        elif (dev, cmd) == (0, 0):
            answer(bytes([pl[0]]) + bytes(FIRMWARE[1:]))
        elif (dev, cmd) == (0, 1):
            self.name = pl.rstrip(b"\0").decode("utf-8", "replace")
        elif (dev, cmd) == (0, 2):
            answer(self.name.encode("utf-8")[:16])
        elif (dev, cmd) in ((0, 7), (0, 9)):
            for i in range(16):
                self._enabled[i] = self._enabled[i] | pl[i] if cmd == 7 else \
                    self._enabled[i] & ~pl[i] & 0xFF
        elif (dev, cmd) == (0, 11):
            answer(bytes(self._enabled))
        elif (dev, cmd) == (0, 14):
            answer(b"EMU-0000000001")
        elif (dev, cmd) == (0, 15):
            answer(b"C3-EMULATED")
        elif (dev, cmd) == (14, 1):
            answer(self._stamp(now) + struct.pack(">HB", 14_400, 87))
        elif (dev, cmd) == (5, 0):
            (_, ms) = struct.unpack(">IH", pl[:6])
            answer(b"", now + ms / 1000)
        elif (dev, cmd) == (5, 4):
            answer(b"", now + 0.5)
        elif (dev, cmd) == (16, 1):
            answer(self._stamp(now) + struct.pack(">hhh", 0, 0, 1000))
        elif (dev, cmd) == (11, 1):
            answer(self._stamp(now) + bytes(12))
        elif (dev, cmd) == (11, 2):
            answer(self._stamp(now) + bytes(12))
        elif (dev, cmd) == (100, 1):
            answer(bytes(12))
        self._check_bumper(now)


class EmulatorBackend:
    """An ``irobot-edu-sdk`` backend (``connect``, ``is_connected``, ``disconnect``,
    ``read_packet``, ``write_packet``) driving a :class:`Create3Emulator`.

    Parameters
    ----------
    env : Environment
    start : (x [m], y [m], heading [deg]), optional
        Where the robot is put down (default: the twin's, cell 0 facing east).
    body : {"kinematic"}
        The emulated body (the kinematic twin).
    noise : NoiseModel, optional
        Spin slip (default exact); ``rng`` draws it.
    time : {"real", "lockstep"}
        ``real``: the robot moves by the wall clock, as a user script expects.
        ``lockstep``: emulated time on a :class:`~bouncesim.robots.create3.clock.VirtualTimeLoop`,
        which the backend makes the current event loop (so ``Create3(backend)``, built next,
        runs on it): the same run on any machine, as fast as the CPU goes.
    **options
        :class:`Create3Emulator`'s: ``reflex``, ``slowdown``, ``reflex_distance``,
        ``slowdown_distance``, ``glance_deg``, ``faults``, ``name``.

    Attributes
    ----------
    emulator : Create3Emulator
    loop : asyncio event loop or None   the lockstep loop (None in real time)
    """

    def __init__(self, env: Environment, *, start=None, body: str = "kinematic",
                 noise: NoiseModel | None = None, rng=None, time: str = "real",
                 **options) -> None:
        if body != "kinematic":
            raise UserError(f"the Create 3 emulator's body is the kinematic twin; got {body!r}.")
        if time not in ("real", "lockstep"):
            raise UserError(f"time must be 'real' or 'lockstep', got {time!r}.")
        self.emulator = Create3Emulator(env, start=start, noise=noise, rng=rng, **options)
        self.time = time
        self.loop = None
        if time == "lockstep":
            self.loop = VirtualTimeLoop()
            asyncio.set_event_loop(self.loop)
        self._queue: asyncio.Queue | None = None
        self._handle = None
        self._running = None
        self._t0 = None

    # ------------------------------------------------------------------ clock
    def _now(self) -> float:
        if self._t0 is None:
            return 0.0
        return self._running.time() - self._t0

    def _pump(self) -> None:
        """Advance the robot to now, deliver what it sent, schedule the next wake."""
        if self.loop is not None:
            self.loop.activity()
        emu, now = self.emulator, self._now()
        emu.advance(now)
        for raw in emu.due(now):
            self._queue.put_nowait(raw)
        if self._handle is not None:
            self._handle.cancel()
            self._handle = None
        if not emu.connected:
            self._queue.put_nowait(None)            # wakes a reader: the link is down
            return
        wake = emu.next_wake(now)
        if wake is not None:
            self._handle = self._running.call_at(self._t0 + max(wake, now), self._pump)

    # ------------------------------------------------------------------ Backend
    async def connect(self) -> None:
        """Connect (waits for ever if the robot never answers, as the Bluetooth backend's
        scan does).
        """
        self._queue = asyncio.Queue()
        self._running = asyncio.get_running_loop()
        self._t0 = self._running.time()
        if not self.emulator.connect(0.0):
            while True:
                await asyncio.sleep(1.0)
        self._pump()

    async def is_connected(self) -> bool:
        """True while the link is up."""
        return self.emulator.connected

    async def disconnect(self) -> None:
        """Drop the link (the robot stops)."""
        if self._queue is None:
            return
        if self._t0 is not None and self.emulator.connected:
            self.emulator.disconnect(self._now())
        self._pump()

    async def write_packet(self, packet) -> None:
        """Obey a packet (the SDK's ``Packet`` or ours; anything with ``to_bytes``)."""
        if self._t0 is None or not self.emulator.connected:
            raise ConnectionError("the emulated Create 3 is not connected.")
        self.emulator.receive(bytes(packet.to_bytes()), self._now())
        self._pump()

    async def read_packet(self):
        """The next packet from the robot, as the SDK's ``Packet`` when the SDK is installed.
        Raises ConnectionError once the link is down and nothing is left to read.
        """
        if self._queue is None:
            raise ConnectionError("the emulated Create 3 is not connected.")
        raw = await self._queue.get()
        if raw is None:
            self._queue.put_nowait(None)            # for every later reader too
            raise ConnectionError("the emulated Create 3 disconnected.")
        return _sdk_packet(raw)

    # ------------------------------------------------------------------ simulation only
    def true_pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], heading [deg]) of the body, for logging and tests."""
        return self.emulator.body.true_pose()

    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the robot down at a pose (against a wall: the robot reports the bump)."""
        now = self._now()
        self.emulator.place(x, y, heading_deg, now)
        if self._queue is not None:
            self._pump()


@functools.lru_cache(maxsize=1)
def _sdk_packet_class():
    try:
        from irobot_edu_sdk.packet import Packet as SDKPacket
    except ImportError:
        return None
    return SDKPacket


def _sdk_packet(raw: bytes):
    """The SDK's ``Packet`` of ``raw`` when the SDK is installed (its CRC kept as received, so
    the SDK's check sees a corrupted packet as corrupted), else the raw bytes.
    """
    cls = _sdk_packet_class()
    return raw if cls is None else cls.from_bytes(raw)


def raw_bytes(packet) -> bytes:
    """The 20 bytes of a received packet as they arrived (the SDK's ``Packet``, whose
    ``to_bytes`` recomputes the CRC, or raw bytes).
    """
    if isinstance(packet, (bytes, bytearray)):
        return bytes(packet)
    return bytes(packet.packet()) + bytes([packet.crc])

