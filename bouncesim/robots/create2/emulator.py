"""An iRobot Create 2 emulator that speaks the Open Interface byte protocol.

:class:`OIEmulator` serves the OI on a pseudo-terminal (``os.openpty``; connect to the printed
``/dev/pts/N``) or on a local TCP port (connect to ``socket://127.0.0.1:PORT``, pyserial's URL
for a raw socket), and moves a simulated Create 2 in an environment with the kinematic twin
(:class:`bouncesim.robots.kinematic.KinematicRobot`). It exists so that the hardware path (the
adapter :mod:`bouncesim.robots.create2.adapter`, pyserial, the OI layer
:mod:`bouncesim.robots.create2.oi`) can be run end to end, and tested, without a robot.

What it does
------------
- Parses the opcodes the adapter uses: Start 128, Safe 131, Full 132, Stop 173, Reset 7,
  Drive 137, Drive Direct 145, Sensors 142, Query List 149, Stream 148, Pause/Resume 150
  (others are ignored). A command waits for all its data bytes, as on the robot.
- Tracks the OI mode (Off, Passive, Safe, Full). Drive commands count only in Safe and Full.
  A wheel drop in Safe mode stops the motors and drops to Passive; in Full mode the motors run
  on (but a lifted robot goes nowhere).
- Answers Sensors / Query List at once and sends stream frames with checksums every 15 ms of
  emulated time. Packets: 7 (bumps, wheel drops), 19/20 (distance, angle since the last
  read, from the encoders), 35 (OI mode), 39-42 (requested velocities), 43/44 (encoders,
  16-bit wrapping), 54/55 (wheel motor currents), battery figures; others read 0.
- Moves the body with the wheel speeds, in emulated time: straight motion and contacts are
  the kinematic twin's (the body stops at the wall, the bumper reads the contact side),
  spins rotate in place, other wheel pairs follow the differential-drive arc in 5 ms
  sub-steps. Encoders count the wheels' own turning (wheels of a blocked body slip; a
  stalled wheel does not turn).

Faults (for tests and demonstrations)
-------------------------------------
- ``noise``: a :class:`bouncesim.robots.noise.NoiseModel` applied once per in-place spin (at its
  end, to the whole spin; a spin ends when the wheels stop, reverse or stop spinning in
  place, not when they slow down): the body slips, the encoders do not see it.
- ``angle_bug``: packet 20 is scaled by 0.324056 (firmware up to 3.4.0).
- scheduled or immediate (:meth:`OIEmulator.inject`): ``wheel-drop``, ``charger`` (the
  robot sees a charger: Safe drops to Passive, no wheel-drop bits), ``stall-left``,
  ``stall-right`` (that wheel stops turning; its encoder stops and its motor current rises),
  ``drop-byte`` (one byte of the next outgoing frame is lost), ``garbage`` (random bytes are
  sent), ``mute`` (the robot stops talking: a lost link; commands are still obeyed, so the
  robot keeps its last drive command, as a real one whose cable is pulled).

Time can run faster than real time (``time_scale``): emulated seconds per wall-clock second. The
adapter must then be given the same scale (:class:`bouncesim.robots.create2.Create2Robot`
``time_scale``), so that its clock and the emulator's agree. Real hardware always runs at 1.

Or time can run in lockstep with an adapter in the same process (``lockstep=True``; see
:mod:`bouncesim.robots.create2.lockstep`): the emulated clock moves only when the adapter has
read the sensor frame it is owed and asks for the next one, so a run gives the same bytes and
the same poses on any machine, however busy. ``Create2Robot(emu.url, emulator=emu)`` picks this
up by itself.

Examples
--------
>>> import envs
>>> import serial
>>> from bouncesim.robots.create2 import oi
>>> with OIEmulator(envs.load("lab"), transport="tcp") as emu:
...     link = serial.serial_for_url(emu.url, timeout=1.0)
...     _ = link.write(bytes([oi.START, oi.SAFE]) + oi.encode_query_list([35, 7]))
...     reply = link.read(2)
...     link.close()
>>> oi.decode_packets([35, 7], reply)
{35: 2, 7: 0}
"""

from __future__ import annotations

import math
import select
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable

import numpy as np

from envs import Environment, UserError

from ..base import CREATE2
from ..noise import NoiseModel
from ..wheel_body import WheelBody
from . import oi
from .faults import Fault
from .lockstep import Lockstep
from .transport import Transport

__all__ = ["OIEmulator", "BANNER"]

BANNER = b"\r\nbouncesim OI emulator\r\nfirmware: emulated 3.4.1\r\n"
"""Sent after a Reset (7), like the robot's boot banner."""

_PERIOD = CREATE2.sensor_period        # [s] of emulated time between stream frames


class OIEmulator:
    """A Create 2 on a pseudo-terminal or a local TCP port, moving in ``env``.

    Parameters
    ----------
    env : Environment
    noise : NoiseModel, optional
        Body slip per in-place spin (default exact).
    rng : numpy.random.Generator or int, optional
        Draws the noise, the dropped byte's position and the garbage. Required when the noise
        is not exact (:func:`bouncesim.robots.noise.noise_and_rng`); without one the faults
        draw from fresh entropy.
    transport : {"pty", "tcp"}
    host, port : str, int
        TCP only: where to listen (port 0 picks a free port; loopback by default).
    time_scale : float
        Emulated seconds per wall-clock second (1: real time).
    angle_bug : bool
        Report packet 20 scaled by 0.324056.
    faults : sequence of Fault
        Scheduled faults (times after the first non-zero drive command).
    encoder_offset : (int, int)
        Initial (left, right) encoder counts, e.g. near 32767 to exercise wrap-around.
    start : (x [m], y [m], heading [deg]), optional
        Initial pose (default: the kinematic twin's, cell 0 facing east).
    glance_deg : float or None
        The twin's glancing-contact arc (default 80°, the PyBullet bumper's): a wall met more
        than this far from the heading does not close the bumper, the body slides along it.
        Turns by encoders or clock end a fraction of a degree off; with None (every front
        contact closes the bumper) a robot that turned 89.7° away from a wall it touches
        would read a bump at once, which a real bumper does not do.
    mode_offset : int
        Added to packet 35 (some units report the OI mode off by one).
    lockstep : bool
        Run the emulated clock in lockstep with an in-process adapter instead of by the wall
        clock (``time_scale`` is then ignored); :attr:`lockstep` is the shared
        :class:`bouncesim.robots.create2.lockstep.Lockstep`.
    log : callable, optional
        Called with one line of text per event (connection, mode change, fault).

    Notes
    -----
    Start it with :meth:`start` (or a ``with`` block), connect to :attr:`url`, stop it with
    :meth:`close`. :meth:`place`, :meth:`true_pose`, :attr:`wheel_command`, :attr:`mode` and
    :attr:`opcodes` are thread-safe views for simulations and tests.
    """

    def __init__(self, env: Environment, noise: NoiseModel | None = None,
                 rng: np.random.Generator | int | None = None, *,
                 transport: str = "pty", host: str = "127.0.0.1", port: int = 0,
                 time_scale: float = 1.0, angle_bug: bool = False,
                 faults: Iterable[Fault] = (),
                 encoder_offset: tuple[int, int] = (0, 0),
                 start: tuple[float, float, float] | None = None,
                 glance_deg: float | None = 80.0, mode_offset: int = 0, lockstep: bool = False,
                 log: Callable[[str], None] | None = None) -> None:
        if not (math.isfinite(time_scale) and 0 < time_scale <= 20):
            raise UserError(f"time scale must lie in (0, 20], got {time_scale:g}.")
        self.env = env
        self.time_scale = float(time_scale)
        self.body = WheelBody(env, noise, rng, start=start, glance_deg=glance_deg)
        self.noise = self.body.noise
        self.rng = self.body.rng if self.body.rng is not None else np.random.default_rng()
        self.angle_bug = bool(angle_bug)                # (the faults' random bytes use rng)
        self.faults = tuple(faults)
        self._log = log
        self.spec = self.body.spec
        self._enc_offset = (int(encoder_offset[0]), int(encoder_offset[1]))
        self._transport = Transport(transport, host, port)
        self.url = self._transport.url
        self.lockstep = Lockstep(_PERIOD) if lockstep else None
        self._rx = 0                               # bytes received from the controller
        self._lock = threading.RLock()
        self._stop_evt = threading.Event()
        self._thread: threading.Thread | None = None
        self._parser = oi.CommandParser()
        # state
        self.mode = oi.MODE_OFF
        self._right = self._left = 0               # accepted wheel command [mm/s]
        self._stalled = self.body.stalled
        self._requested = (0, 0)                   # (velocity, radius) of the last Drive
        self._stream_ids: list[int] | None = None
        self._stream_on = False
        self._wheel_drop = False
        self._muted = False
        self._drop_next = False
        self._first_drive: float | None = None
        self._pending_faults = sorted(self.faults, key=lambda f: f.at)
        self._t0_wall = time.monotonic()
        self._next_tick = _PERIOD
        self.opcodes: Counter = Counter()
        self.packets_requested: Counter = Counter()
        self.mode_offset = int(mode_offset)
        self.frames_sent = 0

    # ------------------------------------------------------------------ life cycle
    def start(self) -> OIEmulator:
        """Start serving in a background thread; returns self."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._serve, name="oi-emulator",
                                            daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop serving and release the pty / socket (idempotent)."""
        self._stop_evt.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        with self._lock:
            self._transport.close()
        if self.lockstep is not None:
            self.lockstep.close()

    def __enter__(self) -> OIEmulator:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ views
    def clock(self) -> float:
        """Emulated time [s] since the emulator was built."""
        if self.lockstep is not None:
            return self.lockstep.now()
        return (time.monotonic() - self._t0_wall) * self.time_scale

    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the robot down at a pose (a person placing it; clears a wheel drop)."""
        with self._lock:
            self._advance_to(self.clock())
            self.body.place(x, y, heading_deg)
            self._wheel_drop = False

    def true_pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], heading [deg]) now."""
        with self._lock:
            self._advance_to(self.clock())
            return self.body.true_pose()

    @property
    def wheel_command(self) -> tuple[int, int]:
        """(right, left) wheel velocities [mm/s] the robot is executing."""
        with self._lock:
            return self._right, self._left

    @property
    def connections(self) -> int:
        """TCP clients accepted so far."""
        return self._transport.connections

    def inject(self, kind: str) -> None:
        """Make a fault (one of :data:`FAULT_KINDS`) strike now."""
        Fault(kind)
        with self._lock:
            self._advance_to(self.clock())
            self._strike(kind)

    def lower(self) -> None:
        """Put a dropped wheel back on the floor."""
        with self._lock:
            self._wheel_drop = False

    def _note(self, text: str) -> None:
        if self._log is not None:
            self._log(f"[{self.clock():8.3f} s] {text}")

    # ------------------------------------------------------------------ the loop
    def _serve(self) -> None:
        tr = self._transport
        once = self._serve_once if self.lockstep is None else self._serve_lockstep
        while not self._stop_evt.is_set():
            once(tr)
        once(tr, final=True)                   # what the controller sent last (e.g. Stop)

    def _receive(self, tr: Transport, ready) -> None:
        """Read what arrived and obey it (at the current emulated time)."""
        before = tr.connections
        data = tr.read(ready) if ready else b""
        if tr.connections != before:
            self._note(f"controller connected ({tr.connections})")
        self._rx += len(data)
        self._advance_to(self.clock())
        for op, payload in self._parser.feed(data):
            self._execute(op, payload)

    def _serve_lockstep(self, tr: Transport, final: bool = False) -> None:
        """Lockstep: obey bytes as they come; move the clock only when the adapter asks and
        every byte it wrote before asking has been read.
        """
        ls = self.lockstep
        try:
            ready, _, _ = select.select(tr.fds() + [ls.wake_fd], [], [], 0.02 if final else
                                        0.05)
        except (OSError, ValueError):
            return
        with self._lock:
            if self._stop_evt.is_set() and not final:
                return
            if ls.wake_fd in ready:
                ls.drain_wake()
            self._receive(tr, ready)
            want = ls.request()
            if want is None or self._rx < want[0]:
                return
            self._advance_to(want[1])
            if ls.at_boundary() and self._stream_on and self._stream_ids and \
                    self.mode != oi.MODE_OFF:
                self._send(oi.encode_stream_frame(self._frame_items()))
                self.frames_sent += 1
            ls.complete()

    def _serve_once(self, tr: Transport, final: bool = False) -> None:
        """Wait for bytes or the next tick; advance the body, obey commands, stream."""
        wait = max(0.0, (self._next_tick - self.clock()) / self.time_scale)
        try:
            ready, _, _ = select.select(tr.fds(), [], [], 0.02 if final else
                                        min(wait, 0.05))
        except (OSError, ValueError):
            return
        with self._lock:
            if self._stop_evt.is_set() and not final:
                return
            self._receive(tr, ready)
            now = self.body.t
            if now >= self._next_tick:
                self._next_tick += _PERIOD
                if self._next_tick < now:              # fell behind: skip, don't burst
                    self._next_tick = now + _PERIOD
                if self._stream_on and self._stream_ids and self.mode != oi.MODE_OFF:
                    self._send(oi.encode_stream_frame(self._frame_items()))
                    self.frames_sent += 1

    def _send(self, data: bytes) -> None:
        if self._muted:
            return
        if self._drop_next and len(data) > 1:
            i = int(self.rng.integers(0, len(data)))
            data = data[:i] + data[i + 1:]
            self._drop_next = False
            self._note(f"dropped byte {i} of an outgoing frame")
        self._write(data)

    def _write(self, data: bytes) -> None:
        n = self._transport.write(data)
        if self.lockstep is not None:
            self.lockstep.wrote(n)

    # ------------------------------------------------------------------ commands
    def _execute(self, op: int, data: bytes) -> None:
        self.opcodes[op] += 1
        if op == oi.RESET:
            self._set_mode(oi.MODE_OFF)
            self._stream_on = False
            self._write(BANNER)
            return
        if op == oi.START:
            self._set_mode(oi.MODE_PASSIVE)
            return
        if self.mode == oi.MODE_OFF:               # the OI ignores everything but Start
            return
        if op == oi.SAFE:
            self._set_mode(oi.MODE_PASSIVE if self._wheel_drop else oi.MODE_SAFE)
        elif op == oi.FULL:
            self._set_mode(oi.MODE_FULL)
        elif op == oi.STOP:
            self._set_mode(oi.MODE_OFF)
            self._stream_on = False
        elif op == oi.DRIVE:
            v = int.from_bytes(data[0:2], "big", signed=True)
            r = int.from_bytes(data[2:4], "big", signed=True)
            if self.mode in (oi.MODE_SAFE, oi.MODE_FULL):
                self._requested = (v, r)
                self._set_wheels(*_drive_to_wheels(v, r, self.spec.wheel_base * 1000))
        elif op == oi.DRIVE_DIRECT:
            right = int.from_bytes(data[0:2], "big", signed=True)
            left = int.from_bytes(data[2:4], "big", signed=True)
            if self.mode in (oi.MODE_SAFE, oi.MODE_FULL):
                self._requested = ((right + left) // 2, 0)
                self._set_wheels(right, left)
        elif op in (oi.SENSORS, oi.QUERY_LIST):
            ids = list(data) if op == oi.SENSORS else list(data[1:])
            self.packets_requested.update(ids)
            try:
                reply = oi.encode_packets(ids, self._values(oi.expand_ids(ids)))
            except oi.OIError:
                return                             # unknown packet: no reply
            self._send(reply)
        elif op == oi.STREAM:
            ids = list(data[1:])
            try:
                if ids:
                    oi.encode_stream(ids)
            except oi.OIError:
                return
            self.packets_requested.update(ids)
            self._stream_ids = ids
            self._stream_on = bool(ids)
        elif op == oi.PAUSE_RESUME:
            self._stream_on = bool(data[0]) and bool(self._stream_ids)

    def _set_mode(self, mode: int) -> None:
        if mode != self.mode:
            x, y, h = self.body.true_pose()
            self._note(f"OI mode {oi.MODE_NAMES[self.mode]} -> {oi.MODE_NAMES[mode]}; robot "
                       f"at ({x:.3f}, {y:.3f}) facing {h:.1f}°")
        self.mode = mode
        if mode in (oi.MODE_OFF, oi.MODE_PASSIVE):
            self._set_wheels(0, 0)

    def _set_wheels(self, right: int, left: int) -> None:
        right = max(-oi.MAX_WHEEL_MM_S, min(oi.MAX_WHEEL_MM_S, int(right)))
        left = max(-oi.MAX_WHEEL_MM_S, min(oi.MAX_WHEEL_MM_S, int(left)))
        self.body.set_wheels(left, right)
        self._right, self._left = right, left
        if (right or left) and self._first_drive is None:
            self._first_drive = self.clock()

    # ------------------------------------------------------------------ faults
    def _strike(self, kind: str) -> None:
        self._note(f"fault: {kind}")
        if kind == "wheel-drop":
            self._wheel_drop = True
            if self.mode == oi.MODE_SAFE:
                self._set_mode(oi.MODE_PASSIVE)
        elif kind == "charger":
            if self.mode in (oi.MODE_SAFE, oi.MODE_FULL):
                self._set_mode(oi.MODE_PASSIVE)
        elif kind in ("stall-left", "stall-right"):
            self._stalled[kind.split("-")[1]] = True
        elif kind == "drop-byte":
            self._drop_next = True
        elif kind == "garbage":
            junk = self.rng.integers(0, 256, size=int(self.rng.integers(5, 40)))
            junk[:: 4] = oi.STREAM_HEADER            # plenty of false frame headers
            self._write(bytes(int(b) for b in junk))
        elif kind == "mute":
            self._muted = True

    def _due_faults(self, now: float) -> None:
        while self._pending_faults and self._first_drive is not None and \
                now >= self._first_drive + self._pending_faults[0].at:
            self._strike(self._pending_faults.pop(0).kind)

    # ------------------------------------------------------------------ physics
    def _advance_to(self, now: float) -> None:
        if now <= self.body.t:
            return
        self._due_faults(now)
        self.body.lifted = self._wheel_drop
        self.body.advance_to(now)

    # ------------------------------------------------------------------ sensors
    def _values(self, ids) -> dict[int, int]:
        left, right = self.body.bumper()
        bits = (oi.BUMP_LEFT if left else 0) | (oi.BUMP_RIGHT if right else 0)
        if self._wheel_drop:
            bits |= oi.WHEEL_DROP_LEFT | oi.WHEEL_DROP_RIGHT
        mpc = self.spec.metres_per_count
        el, er = (int(round(w / mpc)) for w in self.body.wheel_m)
        vals = {7: bits, 35: (self.mode + self.mode_offset) % 256, 21: 0, 22: 14_800,
                23: -300, 24: 25, 25: 2000, 26: 2696, 38: len(self._stream_ids or ()),
                39: self._requested[0], 40: self._requested[1], 41: self._right, 42: self._left,
                43: _wrap16(el + self._enc_offset[0]), 44: _wrap16(er + self._enc_offset[1])}
        for pid, side, cmd in ((54, "left", self._left), (55, "right", self._right)):
            vals[pid] = 0 if cmd == 0 else (1500 if self._stalled[side] else 150)
        if 19 in ids:
            d = int(self.body.dist_acc)              # the fraction is lost on every read
            self.body.dist_acc -= d
            vals[19] = max(-32768, min(32767, d))
        if 20 in ids:
            a = self.body.angle_acc * (oi.ANGLE_BUG_FACTOR if self.angle_bug else 1.0)
            self.body.angle_acc = 0.0                # and so is the angle's
            vals[20] = max(-32768, min(32767, int(a)))
        return vals

    def _frame_items(self) -> list:
        vals = self._values(oi.expand_ids(self._stream_ids))
        items = []
        for pid in self._stream_ids:
            if pid in oi.GROUPS:
                items.append((pid, {m: vals.get(m, 0) for m in oi.GROUPS[pid]}))
            else:
                items.append((pid, vals.get(pid, 0)))
        return items


def _wrap16(v: int) -> int:
    return ((int(v) + 32768) & 0xFFFF) - 32768


def _drive_to_wheels(v: int, r: int, base_mm: float) -> tuple[int, int]:
    """(right, left) wheel speeds [mm/s] of a Drive (137) command."""
    if r in (oi.RADIUS_STRAIGHT, oi.RADIUS_STRAIGHT_ALT) or r == 0:
        return v, v
    if r == oi.RADIUS_CCW:
        return v, -v
    if r == oi.RADIUS_CW:
        return -v, v
    right = v * (r + base_mm / 2) / r
    left = v * (r - base_mm / 2) / r
    return int(round(right)), int(round(left))
