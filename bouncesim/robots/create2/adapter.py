"""A real iRobot Create 2 behind the :class:`bouncesim.robots.base.Robot` interface, over pyserial.

The adapter speaks the Create 2 Open Interface through our own byte-level layer
(:mod:`bouncesim.robots.create2.oi`). It works the same on the robot's USB cable
(``/dev/ttyUSB0``), on a pseudo-terminal and on a TCP socket (``socket://127.0.0.1:PORT``),
which is how it is tested against :class:`bouncesim.robots.create2.OIEmulator`.

Protocol use
------------
- Connect: Start (128), then Safe (131), or Full (132) on request with a warning (no cliff or
  wheel-drop stops at all), then a zero Drive Direct.
- Sensing, every 15 ms: packets 7 (bumps, wheel drops), 43/44 (encoders) and 35 (OI mode),
  either by Stream (148; frames checked by checksum, the parser resynchronises after garbage
  or lost bytes) or by Query List (149; the input is flushed before each query, the reply
  length is checked, a short or over-long reply is retried).
- Driving: Drive Direct (145), right wheel first.
- Turning in place: by the wheel encoders (43/44, unwrapped across the 16-bit wrap) or by the
  clock alone (the paper's robot). The angle packet (20) is never used: firmware up to 3.4.0
  reports it scaled by 0.324056 and every read loses the fraction.
- Closing: a zero Drive Direct, Pause Stream, Stop (173).

Safety
------
Every exit path tries to stop the wheels: ``stop`` in the executors' ``finally`` blocks,
``close`` (the ``with`` block), an ``atexit`` hook, a SIGTERM handler (installed when the
adapter is built in the main thread and SIGTERM has its default action; it stops the robot,
then exits with status 143 through the normal clean-up), and Ctrl-C (KeyboardInterrupt runs
the same ``finally`` blocks). A background thread watches the link while the port is open:

- a wheel drop (packet 7 bits 2-3), or packet 35 reading Passive/Off after it once read the
  requested mode, stops the robot and raises :class:`bouncesim.robots.base.RobotError` at the next
  call (packet 35 is unreliable on some units: when it never reads the requested mode the
  adapter warns once and relies on the wheel-drop bits);
- no valid sensor data for ``link_timeout`` wall-clock seconds, or a serial error: the link
  is lost (a stop is still tried);
- a wheel commanded to move whose encoder has not counted for ``stall_time`` seconds
  (except while both wheels drive forward against a pressed bumper): stalled or blocked;
- the watchdog: a drive command left running while nobody reads the sensors (no call into
  the adapter) for ``watchdog`` seconds is stopped. Every method that drives (``wait``,
  ``turn``, ``drive_until_bump``) polls the sensors while the wheels turn.

``drive_until_bump`` never drives farther than ``max_distance`` without a bump.

Examples
--------
Against the emulator (a real robot: ``Create2Robot("/dev/ttyUSB0")``, placed by hand), in
lockstep so that the emulated clock moves only when the adapter reads (a busy host cannot
starve the reader; by the wall clock use ``time_scale``):

>>> import envs
>>> from bouncesim.robots.create2 import OIEmulator
>>> emu = OIEmulator(envs.load("lab"), lockstep=True).start()
>>> with Create2Robot(emu.url, emulator=emu) as bot:
...     bot.place(0.51, 0.51, 90.0)
...     ev = bot.drive_until_bump(0.5, 10.0)
...     x, y, h = bot.true_pose()
>>> ev.bumped, ev.left and ev.right, round(y, 2)
(True, True, 1.87)
>>> emu.close()
"""

from __future__ import annotations

import atexit
import math
import socket
import threading
import time
import warnings
from typing import TYPE_CHECKING, Any

from envs import UserError

from ..base import (
    CREATE2,
    BumpEvent,
    EmulatedDeclarations,
    Robot,
    RobotError,
    RobotSpec,
    SigtermStop,
)
from . import oi
from .sensing import SENSOR_IDS, SensingMixin, SensorState
from .turning import TurningMixin

if TYPE_CHECKING:
    from .emulator import OIEmulator

__all__ = ["Create2Robot", "SensorState", "SENSOR_IDS"]

class Create2Robot(SigtermStop, EmulatedDeclarations, SensingMixin, TurningMixin, Robot):
    """An iRobot Create 2 over its Open Interface.

    Parameters
    ----------
    port : str
        Serial device (``/dev/ttyUSB0``, ``COM3``), pseudo-terminal path, or any pyserial URL
        (``socket://127.0.0.1:8765`` for the emulator on TCP).
    mode : {"safe", "full"}
        OI mode to drive in. Full disables the robot's own cliff, wheel-drop and charger
        stops (a warning is issued); the adapter's own checks stay on.
    turn : {"encoders", "clock"}
        Turn in place until the encoders show the angle, or for the time the angle takes at
        the turn speed (the paper's clock-only robot).
    turn_speed : float
        Wheel speed of in-place turns [m/s].
    turn_control : {"predictive", "plain"}
        Encoder turns: ``predictive`` (default) slows the wheels near the target, stops where
        the angle will be when the stop command lands (from the measured age of the reading
        and the command latency), and corrects a measured miss with short turns at creep
        speed; ``plain`` stops at the first reading within half a reading of the target (a
        late reading on a busy host overshoots). See docs/readme_hardware.md.
    turn_tolerance : float
        [deg] predictive turns correct a measured miss larger than this.
    sensing : {"stream", "query"}
        Read the sensors from a Stream (148) or by Query List (149) every sensor period.
    baudrate : int
        115200 for the Create 2 (ignored by pseudo-terminals and sockets).
    time_scale : float
        Robot seconds per wall-clock second: 1 on hardware; the emulator's ``time_scale``
        when driving an emulator that runs faster than real time.
    emulator : OIEmulator, optional
        An in-process emulator behind ``port``: :meth:`place` and :meth:`true_pose` go to it
        (simulation only; on hardware ``place`` raises NotImplementedError). When it runs in
        lockstep (``OIEmulator(..., lockstep=True)``) the adapter's clock is the emulated one
        and ``time_scale`` is ignored: see :mod:`bouncesim.robots.create2.lockstep`.
    max_distance : float
        ``drive_until_bump`` gives up (no bump) after this distance [m].
    watchdog, stall_time : float
        [s] of robot time, see the module notes.
    link_timeout : float
        [s] spent listening without a valid sensor frame before the link counts as lost
        (time the host did not run the reader does not count; in lockstep, robot time).
    connect_timeout : float
        [s] of wall time to wait for the first sensor reading.
    handle_sigterm : bool
        Install the stopping SIGTERM handler (main thread only, when SIGTERM has its default
        action).
    link : serial-like, optional
        An already open port object (read, write, in_waiting, reset_input_buffer, close)
        instead of opening ``port``.
    own_emulator : bool
        Close ``emulator`` when the robot is closed.
    spec : RobotSpec, optional
    """

    def __init__(self, port: str | None, *, mode: str = "safe", turn: str = "encoders",
                 turn_speed: float = 0.1, turn_control: str = "predictive",
                 turn_tolerance: float = 0.4, sensing: str = "stream", baudrate: int = 115200,
                 time_scale: float = 1.0, emulator: OIEmulator | None = None,
                 max_distance: float = 10.0,
                 watchdog: float = 1.0, link_timeout: float = 0.5, stall_time: float = 0.5,
                 connect_timeout: float = 5.0, handle_sigterm: bool = True, link: Any = None,
                 own_emulator: bool = False, spec: RobotSpec | None = None) -> None:
        self.spec = spec if spec is not None else CREATE2
        if mode not in ("safe", "full"):
            raise UserError(f"OI mode must be 'safe' or 'full', got {mode!r}.")
        if turn not in ("encoders", "clock"):
            raise UserError(f"turn must be 'encoders' or 'clock', got {turn!r}.")
        if turn_control not in ("predictive", "plain"):
            raise UserError(f"turn control must be 'predictive' or 'plain', got "
                            f"{turn_control!r}.")
        if not (math.isfinite(turn_tolerance) and 0.05 <= turn_tolerance <= 10):
            raise UserError(f"turn tolerance must lie in [0.05, 10] degrees, got "
                            f"{turn_tolerance:g}.")
        if sensing not in ("stream", "query"):
            raise UserError(f"sensing must be 'stream' or 'query', got {sensing!r}.")
        if not 0 < turn_speed <= self.spec.max_wheel_speed:
            raise UserError(f"turn speed must lie in (0, {self.spec.max_wheel_speed:g}] m/s, "
                            f"got {turn_speed:g}.")
        if not (math.isfinite(time_scale) and 0 < time_scale <= 20):
            raise UserError(f"time scale must lie in (0, 20], got {time_scale:g}.")
        self.port = port
        self.mode = mode
        self.turn_mode = turn
        self.turn_speed = float(turn_speed)
        self.turn_control = turn_control
        self.turn_tolerance = float(turn_tolerance)
        self.sensing = sensing
        self.time_scale = float(time_scale)
        self.emulator = emulator
        self._ls = getattr(emulator, "lockstep", None)      # lockstep with the emulator
        self._tx = 0                                # bytes written / read on the link
        self._rx = 0
        self._last_valid = 0.0                      # robot time of the last valid reading
        self._latency = self.spec.sensor_period     # age of a reading when acted on [s]
        self.own_emulator = bool(own_emulator)
        self.max_distance = float(max_distance)
        self.watchdog = float(watchdog)
        self.link_timeout = float(link_timeout)
        self.stall_time = float(stall_time)
        self.connect_timeout = float(connect_timeout)
        self._expected_mode = oi.MODE_SAFE if mode == "safe" else oi.MODE_FULL
        self._mode_checked = False
        self._t0 = time.monotonic()
        self._cv = threading.Condition()            # guards the state below
        self._wlock = threading.RLock()             # one writer / one query at a time
        self._state: SensorState | None = None
        self._raw: tuple[int, int] | None = None    # last raw 16-bit encoder readings
        self._counts = (0, 0)
        self._fault: RobotError | None = None
        self._cmd = (0, 0)                          # (right, left) commanded [mm/s]
        self._stall_mark: list = [None, None]       # per wheel (left, right): (count, t)
        self._last_call = 0.0
        self._last_query = -math.inf
        self._closed = False
        self._closing = False
        self._thread: threading.Thread | None = None
        self._parser = oi.StreamParser(SENSOR_IDS)
        self._ser = link if link is not None else self._open(port, baudrate)
        atexit.register(self.close)
        try:
            self._connect()
        except BaseException:
            self.close()
            raise
        if handle_sigterm:
            self._install_sigterm()

    # ------------------------------------------------------------------ connection
    def _open(self, port, baudrate):
        if port is None:
            raise UserError("the Create 2 adapter needs a serial port (--port).")
        try:
            import serial
        except ModuleNotFoundError:
            raise UserError("the Create 2 adapter needs pyserial: pip install -e "
                            "'.[hardware]'.") from None
        try:
            ser = serial.serial_for_url(port, baudrate=baudrate, timeout=0.02,
                                        write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise UserError(f"cannot open serial port {port}: {exc}.") from None
        sock = getattr(ser, "_socket", None)        # socket:// URL: send small frames now
        if sock is not None:
            try:
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            except OSError:
                pass
        return ser

    def _connect(self) -> None:
        self._write(bytes([oi.START]))
        time.sleep(0.02)
        if self.mode == "full":
            warnings.warn("Full mode: the robot's own cliff, wheel-drop and charger safety "
                          "stops are off; only the adapter's checks remain.", stacklevel=3)
            self._write(bytes([oi.FULL]))
        else:
            self._write(bytes([oi.SAFE]))
        time.sleep(0.02)
        self._write(oi.encode_drive_direct(0, 0))
        self._flush_input()
        if self.sensing == "stream":
            self._write(oi.encode_stream(SENSOR_IDS))
            self._write(oi.encode_pause_resume(True))
            self._thread = threading.Thread(target=self._reader, name="create2-reader",
                                            daemon=True)
        else:
            self._thread = threading.Thread(target=self._watchdog_loop,
                                            name="create2-watchdog", daemon=True)
        self._thread.start()
        # the first readings: the link works, and does packet 35 report the requested mode?
        deadline = time.monotonic() + self.connect_timeout
        seen_modes = []
        while time.monotonic() < deadline and len(seen_modes) < 4:
            st = self._next_state(None if self._state is None else self._state.seq,
                                  self.clock() + 0.2, check=False)
            if st is None:
                continue
            seen_modes.append(st.mode)
            if st.mode == self._expected_mode:
                with self._cv:
                    self._mode_checked = True
                break
        if not seen_modes:
            raise RobotError(f"no sensor data from {self.port} within "
                             f"{self.connect_timeout:g} s: is the robot switched on and the "
                             "cable plugged in?")
        self._raise_fault()
        if not self._mode_checked:
            warnings.warn(f"packet 35 (OI mode) read {seen_modes[-1]} instead of "
                          f"{self._expected_mode}; mode checks are off, wheel drops are "
                          "still detected.", stacklevel=3)

    def _on_sigterm(self) -> None:
        self.stop()                               # a serial write: safe in the handler

    # ------------------------------------------------------------------ low level
    def _write(self, data: bytes) -> None:
        """Send one whole command (never a partial frame) or fail with a RobotError."""
        try:
            with self._wlock:
                self._ser.write(data)
                self._tx += len(data)
        except Exception as exc:                  # serial, OS and socket errors alike
            err = RobotError(f"lost the serial link to {self.port}: {exc}")
            self._set_fault(err)
            raise err from None

    def _flush_input(self) -> None:
        if self._ls is not None:                   # lockstep: read what was sent, to count it
            self._read_until(self._ls.robot_bytes)
        else:
            try:
                self._ser.reset_input_buffer()
            except Exception:                      # noqa: BLE001 - best effort
                pass
        self._parser.reset()

    def _read_until(self, total: int) -> bytes:
        """Lockstep: read until ``total`` bytes have arrived on the link since it opened."""
        data = bytearray()
        end = time.monotonic() + self._ls.wall_timeout
        while self._rx < total and time.monotonic() < end:
            chunk = self._ser.read(total - self._rx)
            self._rx += len(chunk)
            data += chunk
        return bytes(data)

    def _set_fault(self, err: RobotError, stop: bool = False) -> None:
        with self._cv:
            if self._fault is None and not self._closing:
                self._fault = err
            self._cv.notify_all()
        if stop:
            self._send_stop()

    def _raise_fault(self) -> None:
        if self._fault is not None:
            raise self._fault

    def _send_stop(self) -> bool:
        """Best effort zero Drive Direct; True when it was written."""
        try:
            data = oi.encode_drive_direct(0, 0)
            with self._wlock:
                self._ser.write(data)
                self._tx += len(data)
            with self._cv:
                self._cmd = (0, 0)
            return True
        except Exception:                          # noqa: BLE001 - the link may be gone
            return False

    def _drive_direct(self, right: float, left: float) -> None:
        """Command wheel speeds [m/s] (right first, as the OI takes them)."""
        self._raise_fault()
        r, l_ = int(round(right * 1000)), int(round(left * 1000))
        with self._cv:
            self._last_call = self.clock()
        self._write(oi.encode_drive_direct(r, l_))
        with self._cv:
            self._cmd = (r, l_)
            t = self.clock()
            self._stall_mark = [(self._counts[0], t), (self._counts[1], t)]

    # ------------------------------------------------------------------ Robot interface
    def drive(self, speed: float) -> None:
        """Drive straight at ``speed`` [m/s] (both wheels) until stopped."""
        speed = self.spec.check_speed(speed)
        self._drive_direct(speed, speed)

    def stop(self) -> None:
        """Stop both wheels (best effort: never raises, the link may be gone)."""
        if self._ser is not None and not self._closed:
            self._send_stop()

    def bumper(self) -> tuple[bool, bool]:
        """The (left, right) bumper state from a fresh sensor frame."""
        self._raise_fault()
        st = self._fresh(2 if self.sensing == "stream" else 1)
        return st.bump_left, st.bump_right

    def clock(self) -> float:
        """The robot clock [s] since connecting (emulated time under lockstep or a time scale)."""
        if self._ls is not None:
            return self._ls.now()
        return (time.monotonic() - self._t0) * self.time_scale

    def wait(self, duration: float) -> None:
        """Wait ``duration`` [s] on the robot clock while reading sensors (faults raise)."""
        duration = float(duration)
        if duration < 0 or not math.isfinite(duration):
            raise ValueError(f"cannot wait {duration} s.")
        self._raise_fault()
        end = self.clock() + duration
        seq = None if self._state is None else self._state.seq
        lag = 0.0
        while True:
            st = self._next_state(seq, end - lag)
            if st is None:
                return
            lag = self._lag(lag, st)
            if self.clock() + lag / 2 >= end:      # (a slow host may always find a reading)
                return
            seq = st.seq

    def _lag(self, lag: float, st: SensorState) -> float:
        """Running estimate [s] of how late the host acts on a reading (its age when used).
        A timed wait asks for its deadline this much early (the host acts that late on the
        answer), and after a reading it stops when the deadline is nearer than half of it (the
        next chance would come about this late: stopping now misses by less).
        """
        return 0.7 * lag + 0.3 * max(self.clock() - st.t, 0.0)

    def encoders(self) -> tuple[int, int]:
        """The (left, right) wheel encoder counts from a fresh sensor frame."""
        st = self._fresh(1)
        return st.left, st.right

    def drive_until_bump(self, speed: float, timeout: float) -> BumpEvent:
        """Drive at ``speed`` [m/s] until a bump or ``timeout`` [s]; returns the bump event."""
        speed = float(speed)
        timeout = max(0.0, float(timeout))
        if speed > 0:
            timeout = min(timeout, self.max_distance / speed)
        self._raise_fault()
        st = self._state
        seq = None if st is None else st.seq
        t0 = self.clock()
        self.drive(speed)
        lag = 0.0
        try:
            while True:
                st = self._next_state(seq, t0 + timeout - lag)
                if st is None:
                    return BumpEvent(False, False, False, self.clock() - t0)
                seq = st.seq
                if st.bump_left or st.bump_right:
                    return BumpEvent(True, st.bump_left, st.bump_right, max(st.t - t0, 0.0))
                lag = self._lag(lag, st)
                if self.clock() + lag / 2 >= t0 + timeout:  # a slow host: stop nearer
                    return BumpEvent(False, False, False, self.clock() - t0)
        finally:
            self.stop()

    # ------------------------------------------------------------------ simulation only
    def place(self, x: float, y: float, heading_deg: float) -> None:
        """Place the emulated robot at (x [m], y [m], heading [deg]); no-op on hardware."""
        if self.emulator is None:
            return super().place(x, y, heading_deg)
        self.emulator.place(x, y, heading_deg)

    def _emulator(self):
        return self.emulator

    def true_pose(self) -> tuple[float, float, float] | None:
        """The emulator's true pose (x [m], y [m], heading [deg]); None on hardware."""
        return None if self.emulator is None else self.emulator.true_pose()

    # ------------------------------------------------------------------ teardown
    def close(self) -> None:
        """Stop the wheels, pause the stream, turn the OI off (Stop, 173) and release the
        port; idempotent and never raises.
        """
        if self._closed:
            return
        self._closing = True
        ser = getattr(self, "_ser", None)
        if ser is not None:
            for data in (oi.encode_drive_direct(0, 0), oi.encode_pause_resume(False),
                         bytes([oi.STOP])):
                try:
                    with self._wlock:
                        ser.write(data)
                        self._tx += len(data)
                except Exception:                  # noqa: BLE001 - best effort
                    break
        with self._cv:
            self._cmd = (0, 0)
            self._cv.notify_all()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
        if ser is not None:
            try:
                ser.close()
            except Exception:                      # noqa: BLE001
                pass
        self._closed = True
        self._restore_sigterm()
        atexit.unregister(self.close)
        if self.own_emulator and self.emulator is not None:
            self.emulator.close()

    def __repr__(self) -> str:
        return (f"Create2Robot({self.port!r}, mode={self.mode!r}, turn={self.turn_mode!r}, "
                f"sensing={self.sensing!r})")
