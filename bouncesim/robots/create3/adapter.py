"""Our Robot interface on a Create 3: :class:`Create3Robot` speaks the packet layer
(:mod:`.packets`) over any ``irobot-edu-sdk`` backend: the SDK's ``Bluetooth`` for a real robot,
:class:`~bouncesim.robots.create3.emulator.EmulatorBackend` for the emulator.

Why the packet layer and not the SDK's ``Create3`` object: the SDK's ``Robot`` keeps class-wide
state (every robot ever built is in ``Robot.robots``; ``Robot._run`` is one flag for all),
replaces the process's SIGINT and SIGTERM handlers with ``sys.exit`` when built, waits for
answers by polling the wall clock, and runs its loop for ever from ``play()``. A library that
is called step by step (drive, read the bumper, turn) needs none of that. So the adapter owns
one asyncio loop and runs it only while one of its calls is in progress, in the calling
thread: no background thread, no races, and in lockstep (the emulator's
:class:`~bouncesim.robots.create3.clock.VirtualTimeLoop`) the same run on any machine. The SDK
is still what carries the bytes to a real robot (its ``Bluetooth`` backend, on bleak).

Safety, as the Create 2 adapter: every exit path stops the wheels; a lost link, a missing
answer or a motor stall is one sentence (:class:`~bouncesim.robots.base.RobotError`).
"""

from __future__ import annotations

import asyncio
import math
from dataclasses import replace

from envs import UserError

from ..base import CREATE2, BumpEvent, EmulatedDeclarations, Robot, RobotError, SigtermStop
from .emulator import TURN_DEG_S, raw_bytes
from .packets import MAX_SPEED_MM_S, Packet, bump_event, pose_of

__all__ = ["CREATE3", "Create3Robot"]

CREATE3 = replace(CREATE2, radius=0.171, max_wheel_speed=MAX_SPEED_MM_S / 1000)
"""The Create 3 (a Roomba i3 base): 508.8 encoder counts per wheel turn, 0.306 m/s."""


class Create3Robot(SigtermStop, EmulatedDeclarations, Robot):
    """A Create 3 (or its emulator) as a bump-and-clock :class:`~bouncesim.robots.base.Robot`.

    Parameters
    ----------
    backend : SDK backend
        ``irobot_edu_sdk.backend.bluetooth.Bluetooth(name)`` for a robot, or an
        :class:`~bouncesim.robots.create3.emulator.EmulatorBackend`.
    turn : {"rotate", "clock"}
        ``rotate``: the robot's own turn command (1, 12), which ends on its IMU; ``clock``:
        spin the wheels at ``turn_speed`` for the time the angle needs (the paper's robot).
    turn_speed : float
        Wheel speed [m/s] of clock turns.
    connect_timeout, answer_timeout : float
        Seconds to wait for the connection and for an answer before the link counts as lost.
    handle_sigterm : bool
        SIGTERM ends the program through SystemExit, so the robot is stopped on the way out
        (:class:`~bouncesim.robots.base.SigtermStop`).
    """

    spec = CREATE3

    def __init__(self, backend, *, turn: str = "rotate", turn_speed: float = 0.1,
                 connect_timeout: float = 20.0, answer_timeout: float = 3.0,
                 handle_sigterm: bool = True) -> None:
        if turn not in ("rotate", "clock"):
            raise UserError(f"turn must be 'rotate' or 'clock', got {turn!r}.")
        self.backend = backend
        self.turn_mode = turn
        self.turn_speed = float(turn_speed)
        self.answer_timeout = float(answer_timeout)
        self._loop = getattr(backend, "loop", None) or asyncio.new_event_loop()
        self._inc = 0
        self._pending: dict = {}
        self._bumper = (False, False)
        self._bump: asyncio.Future | None = None
        self._fault: RobotError | None = None
        self._closed = False
        self.dropped = 0                      # packets that failed their CRC
        self._t0 = self._loop.time()
        try:
            self._run(self._connect(), connect_timeout,
                      f"no Create 3 answered within {connect_timeout:g} s; is it on, in "
                      "range and not connected to another program?")
            self.stop()
        except BaseException:
            self._shutdown()
            raise
        if handle_sigterm:
            self._install_sigterm()             # SystemExit: the with block stops the robot

    # ------------------------------------------------------------------ the loop
    def _run(self, coro, timeout: float | None = None, lost: str | None = None,
             check: bool = True):
        """Run ``coro`` on the adapter's loop until done (``timeout`` [s]: the link is lost;
        ``check``: refuse once the robot has failed).
        """
        if check and self._fault is not None:
            coro.close()
            raise self._fault
        if timeout is not None:
            coro = asyncio.wait_for(coro, timeout)
        try:
            return self._loop.run_until_complete(coro)
        except (asyncio.TimeoutError, TimeoutError):
            err = RobotError(lost or "the Create 3 stopped answering.")
            self._set_fault(err)
            raise err from None
        except ConnectionError as exc:
            err = RobotError(f"lost the link to the Create 3: {exc}")
            self._set_fault(err)
            raise err from None

    async def _connect(self) -> None:
        try:
            await self.backend.connect()
        except (OSError, ConnectionError) as exc:
            raise RobotError(f"cannot connect to the Create 3 ({type(exc).__name__}: {exc}); "
                             "is Bluetooth on and this program allowed to use it?") from None
        except Exception as exc:            # bleak's own errors (BleakError, D-Bus, ...)
            if type(exc).__module__.split(".")[0] not in ("bleak", "dbus_fast"):
                raise
            raise RobotError(f"cannot connect to the Create 3 ({type(exc).__name__}: "
                             f"{exc}).") from None
        self._reader = self._loop.create_task(self._read())

    async def _read(self) -> None:
        try:
            while True:
                self._handle(await self.backend.read_packet())
        except ConnectionError as exc:
            self._set_fault(RobotError(f"lost the link to the Create 3: {exc}"))

    def _handle(self, packet) -> None:
        raw = raw_bytes(packet)
        try:
            p = Packet.from_bytes(raw)
        except UserError:
            self.dropped += 1
            return
        bump = bump_event(p)
        if bump is not None:
            self._bumper = (bump[1], bump[2])
            if (bump[1] or bump[2]) and self._bump is not None and not self._bump.done():
                self._bump.set_result(self.clock())
            return
        if (p.device, p.command) == (1, 29):
            side = "right" if p.payload[4] else "left"
            self._set_fault(RobotError(f"the Create 3's {side} wheel motor stalled."))
            return
        fut = self._pending.pop((p.device, p.command, p.inc), None)
        if fut is not None and not fut.done():
            fut.set_result(p)

    def _set_fault(self, err: RobotError) -> None:
        if self._fault is None:
            self._fault = err
        for fut in list(self._pending.values()) + [self._bump]:
            if fut is not None and not fut.done():
                fut.set_exception(err)
        self._pending.clear()

    def _next_inc(self) -> int:
        inc = self._inc
        self._inc = (self._inc + 1) % 256
        return inc

    async def _send(self, packet: Packet) -> None:
        await self.backend.write_packet(packet)

    async def _ask(self, packet: Packet) -> Packet:
        fut = self._loop.create_future()
        self._pending[(packet.device, packet.command, packet.inc)] = fut
        await self.backend.write_packet(packet)
        return await fut

    def _command(self, packet: Packet) -> None:
        self._run(self._send(packet), self.answer_timeout)

    def _query(self, packet: Packet, timeout: float) -> Packet:
        return self._run(self._ask(packet), timeout,
                         f"the Create 3 did not answer command {packet.device}/"
                         f"{packet.command} within {timeout:g} s.")

    # ------------------------------------------------------------------ Robot interface
    def drive(self, speed: float) -> None:
        """Both wheels at ``speed`` [m/s] (sent as whole mm/s, capped at 0.306 m/s)."""
        speed = float(speed)
        if not math.isfinite(speed) or abs(speed) > self.spec.max_wheel_speed + 1e-9:
            raise UserError(f"speed {speed:g} m/s is beyond the Create 3's "
                            f"{self.spec.max_wheel_speed:g} m/s.")
        self._command(Packet.wheel_speeds(speed * 100, speed * 100, self._next_inc()))

    def stop(self) -> None:
        """Both wheels at 0."""
        self._command(Packet.wheel_speeds(0, 0, self._next_inc()))

    def bumper(self) -> tuple[bool, bool]:
        """(left, right) from the latest bump event."""
        self._run(asyncio.sleep(0))
        return self._bumper

    def clock(self) -> float:
        """Seconds since the adapter was built (the loop's clock: emulated in lockstep)."""
        return self._loop.time() - self._t0

    def wait(self, duration: float) -> None:
        """Let ``duration`` [s] pass (events keep arriving)."""
        self._run(asyncio.sleep(max(float(duration), 0.0)))

    def turn(self, angle_deg: float) -> None:
        """Turn CCW by ``angle_deg``: the robot's turn command, or by the clock."""
        angle = float(angle_deg)
        if self.turn_mode == "rotate":
            timeout = abs(angle) / TURN_DEG_S * 2 + self.answer_timeout
            self._query(Packet.turn(angle, self._next_inc(), left=True), timeout)
            return
        w = self.turn_speed * 100 * (1 if angle > 0 else -1)
        try:
            self._command(Packet.wheel_speeds(-w, w, self._next_inc()))
            self.wait(self.spec.turn_time(angle, self.turn_speed))
        finally:
            self._safe_stop()

    def drive_until_bump(self, speed: float, timeout: float) -> BumpEvent:
        """Drive until a bump event arrives or ``timeout`` [s] passes, then stop."""
        self._run(asyncio.sleep(0))
        if self._bumper[0] or self._bumper[1]:
            return BumpEvent(True, *self._bumper, 0.0)
        self._bump = self._loop.create_future()
        t0 = self.clock()
        try:
            self.drive(speed)
            t_bump = self._run(self._bump_within(max(float(timeout), 0.0)))
            if t_bump is None:
                return BumpEvent(False, False, False, self.clock() - t0)
            return BumpEvent(True, *self._bumper, t_bump - t0)
        finally:
            self._bump = None
            self._safe_stop()

    async def _bump_within(self, timeout: float) -> float | None:
        try:
            return await asyncio.wait_for(asyncio.shield(self._bump), timeout)
        except (asyncio.TimeoutError, TimeoutError):
            return None

    def _safe_stop(self) -> None:
        """Stop on an exit path: tried even after a fault, its own failure kept quiet (the
        first error is the one to report).
        """
        if self._fault is None:
            self.stop()
            return
        try:
            self._run(self._send(Packet.wheel_speeds(0, 0, self._next_inc())),
                      self.answer_timeout, check=False)
        except (RobotError, ConnectionError, OSError):
            pass

    def get_position(self) -> tuple[float, float, float]:
        """The robot's own odometry: (x [cm], y [cm], heading [deg]) (1, 16)."""
        return pose_of(self._query(Packet.simple(1, 16, self._next_inc()),
                                   self.answer_timeout))

    # ------------------------------------------------------------------ simulation only
    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Put the emulated robot down at a pose (emulator only)."""
        if not hasattr(self.backend, "place"):
            super().place(x, y, heading_deg)
        self.backend.place(x, y, heading_deg)
        self._run(asyncio.sleep(0))

    def _emulator(self):
        return getattr(self.backend, "emulator", None)

    def true_pose(self) -> tuple[float, float, float] | None:
        """The emulated body's pose; None on a real robot."""
        pose = getattr(self.backend, "true_pose", None)
        return pose() if pose is not None else None

    # ------------------------------------------------------------------ the end
    def close(self) -> None:
        """Stop, say goodbye (stop, disconnect) and release the link (idempotent)."""
        if self._closed:
            return
        self._shutdown()

    def _shutdown(self) -> None:
        self._closed = True
        self._restore_sigterm()
        fault, self._fault = self._fault, None
        try:
            if self._loop.is_closed():
                return
            for packet in (Packet.wheel_speeds(0, 0, self._next_inc()),
                           Packet.simple(0, 3, self._next_inc()),
                           Packet.simple(0, 6, self._next_inc())):
                try:
                    self._run(self._send(packet), self.answer_timeout, check=False)
                except (RobotError, ConnectionError, OSError):
                    break
            try:
                self._run(self.backend.disconnect(), self.answer_timeout, check=False)
            except (RobotError, ConnectionError, OSError):
                pass
            for task in asyncio.all_tasks(self._loop):
                task.cancel()
            self._loop.run_until_complete(asyncio.sleep(0))
        finally:
            self._fault = fault
            if not self._loop.is_closed():
                self._loop.close()

    def __repr__(self) -> str:
        return f"Create3Robot({type(self.backend).__name__}, turn={self.turn_mode!r})"
