"""A real iRobot Create 2 behind the :class:`bouncesim.robots.base.Robot` interface, over pyserial.

The adapter speaks the Create 2 Open Interface through our own byte-level layer
(:mod:`bouncesim.robots.create2.oi`). It works the same on the robot's USB cable
(``/dev/ttyUSB0``), on a pseudo-terminal and on a TCP socket (``socket://127.0.0.1:PORT``),
which is how it is tested against :class:`bouncesim.robots.create2.emulator.OIEmulator`.

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
Against the emulator (a real robot: ``Create2Robot("/dev/ttyUSB0")``, placed by hand):

>>> import envs
>>> from bouncesim.robots.create2.emulator import OIEmulator
>>> emu = OIEmulator(envs.load("lab"), time_scale=4.0).start()
>>> with Create2Robot(emu.url, emulator=emu, time_scale=4.0) as bot:
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
import signal
import socket
import threading
import time
import warnings
from dataclasses import dataclass

from envs import UserError

from . import oi
from .lockstep import LockstepClosed
from ..base import CREATE2, BumpEvent, Robot, RobotError, RobotSpec

__all__ = ["Create2Robot", "SensorState", "SENSOR_IDS"]

SENSOR_IDS = (7, 43, 44, 35)
"""Packets read every sensor period: bumps and wheel drops, encoders, OI mode."""
_MIN_WHEEL = 0.02          # [m/s] below this a wheel command is not checked for a stall
_STALL_COUNTS = 2          # encoder counts that prove a wheel turns
_CREEP_SPEED = 0.015       # [m/s] wheel speed at the end of a predictive turn
_SLOW_ZONE_DEG = 10.0      # [deg] predictive turns slow down over the last this many degrees
_TURN_CORRECTIONS = 3      # measured misses a predictive turn corrects at most


@dataclass(frozen=True)
class SensorState:
    """One reading of :data:`SENSOR_IDS`.

    Attributes
    ----------
    seq : int            reading number (increasing)
    t : float            adapter clock when it arrived [s]
    bump_left, bump_right, wheel_drop : bool
    left, right : int    unwrapped cumulative encoder counts
    mode : int           packet 35 as read (0 Off, 1 Passive, 2 Safe, 3 Full)
    """

    seq: int
    t: float
    bump_left: bool
    bump_right: bool
    wheel_drop: bool
    left: int
    right: int
    mode: int


class Create2Robot(Robot):
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
        [s] of wall-clock time without a valid sensor frame before the link counts as lost.
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
                 time_scale: float = 1.0, emulator=None, max_distance: float = 10.0,
                 watchdog: float = 1.0, link_timeout: float = 0.5, stall_time: float = 0.5,
                 connect_timeout: float = 2.0, handle_sigterm: bool = True, link=None,
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
        self._prev_sigterm = None
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

    def _install_sigterm(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return
        if signal.getsignal(signal.SIGTERM) not in (signal.SIG_DFL, None):
            return

        def on_sigterm(signum, frame):
            self.stop()
            raise SystemExit(128 + signum)

        self._prev_sigterm = signal.getsignal(signal.SIGTERM)
        self._sigterm_handler = on_sigterm
        signal.signal(signal.SIGTERM, on_sigterm)

    def _restore_sigterm(self) -> None:
        if self._prev_sigterm is None:
            return
        try:
            if signal.getsignal(signal.SIGTERM) is self._sigterm_handler:
                signal.signal(signal.SIGTERM, self._prev_sigterm)
        except ValueError:                        # not the main thread
            pass
        self._prev_sigterm = None

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

    # ------------------------------------------------------------------ sensing
    def _reader(self) -> None:
        """Stream mode: read frames, keep the latest state, watch the link and the wheels."""
        last_wall = time.monotonic()
        while not self._closing:
            try:
                n = self._ser.in_waiting
                chunk = self._ser.read(max(1, min(n, 4096)))
            except Exception as exc:               # noqa: BLE001 - any I/O failure
                if not self._closing:
                    self._set_fault(RobotError(f"lost the serial link to {self.port}: {exc}"),
                                    stop=True)
                return
            if chunk:
                for values in self._parser.feed(chunk):
                    self._update(values)
                    last_wall = time.monotonic()
                with self._cv:
                    self._rx += len(chunk)
                    self._cv.notify_all()
            if self._ls is not None:               # lockstep: judged in robot time
                continue
            # the link is judged in wall-clock time (a scaled emulator on a busy machine
            # must not look like a lost link)
            silent = time.monotonic() - last_wall
            if silent > self.link_timeout and self._fault is None:
                self._set_fault(RobotError(
                    f"no valid sensor data from {self.port} for {silent:.2f} s: "
                    "lost the link; tried to stop the robot"), stop=True)
            self._check_watchdog(self.clock())

    def _watchdog_loop(self) -> None:
        """Query mode: only the watchdog runs in the background."""
        while not self._closing:
            time.sleep(0.02)
            self._check_watchdog(self.clock())

    def _check_watchdog(self, now: float) -> None:
        if self._ls is not None:                   # lockstep: time stands still unless asked
            return
        with self._cv:
            driving = self._cmd != (0, 0)
            idle = now - self._last_call
        if driving and idle > self.watchdog and self._fault is None:
            self._set_fault(RobotError(
                f"the wheels were driving while nothing read the sensors for {idle:.2f} s; "
                "stopped by the watchdog"), stop=True)

    def _update(self, values: dict) -> SensorState:
        """Take one reading; detect wheel drops, mode drops and stalls (stopping the robot)."""
        now = self.clock() if self._ls is None else self._ls.reaching()
        bits = values[7]
        raw = (values[43], values[44])
        problem = None
        with self._cv:
            if self._raw is None:
                counts = self._counts
            else:
                counts = (self._counts[0] + oi.encoder_delta(raw[0], self._raw[0]),
                          self._counts[1] + oi.encoder_delta(raw[1], self._raw[1]))
            self._raw, self._counts = raw, counts
            self._last_valid = now
            seq = 0 if self._state is None else self._state.seq + 1
            st = SensorState(seq, now, bool(bits & oi.BUMP_LEFT), bool(bits & oi.BUMP_RIGHT),
                             bool(bits & (oi.WHEEL_DROP_LEFT | oi.WHEEL_DROP_RIGHT)),
                             counts[0], counts[1], values[35])
            self._state = st
            if st.wheel_drop:
                problem = ("a wheel dropped (the robot was lifted or went over an edge); "
                           "the robot leaves Safe mode for Passive; stopped")
            elif self._mode_checked and st.mode in (oi.MODE_PASSIVE, oi.MODE_OFF):
                problem = (f"the robot dropped from {oi.MODE_NAMES[self._expected_mode]} to "
                           f"{oi.MODE_NAMES[st.mode]} mode (wheel drop, cliff or charger); "
                           "stopped")
            else:
                problem = self._stall_check(st)
            self._cv.notify_all()
        if problem is not None and self._fault is None:
            self._set_fault(RobotError(problem), stop=True)
        return st

    def _stall_check(self, st: SensorState) -> str | None:
        cmd_left, cmd_right = self._cmd[1], self._cmd[0]
        if (st.bump_left or st.bump_right) and cmd_left > 0 and cmd_right > 0:
            self._stall_mark = [(st.left, st.t), (st.right, st.t)]   # pushing a wall
            return None
        for i, (name, cmd, count) in enumerate((("left", cmd_left, st.left),
                                                ("right", cmd_right, st.right))):
            mark = self._stall_mark[i]
            if abs(cmd) < _MIN_WHEEL * 1000 or mark is None:
                continue
            if abs(count - mark[0]) >= _STALL_COUNTS:
                self._stall_mark[i] = (count, st.t)
            elif st.t - mark[1] > self.stall_time:
                return (f"the {name} wheel has not turned for {st.t - mark[1]:.2f} s while "
                        f"commanded at {cmd} mm/s (stalled or blocked); stopped")
        return None

    def _query(self, deadline: float = math.inf) -> SensorState | None:
        """Query mode: one Query List exchange, retried after a short or garbled reply; None
        when the robot clock reaches ``deadline`` before the next query is due."""
        if self._ls is not None:
            return self._query_lockstep(deadline)
        need = oi.reply_size(SENSOR_IDS)
        request = oi.encode_query_list(SENSOR_IDS)
        wall_period = self.spec.sensor_period / self.time_scale
        timeout = max(0.05, 4 * wall_period)
        for _ in range(3):
            wait = self._last_query + wall_period - time.monotonic()
            if wait > 0:                            # never poll faster than the robot
                left = (deadline - self.clock()) / self.time_scale
                if left <= wait:
                    time.sleep(max(left, 0.0))
                    return None
                time.sleep(wait)
            try:
                with self._wlock:
                    self._flush_input()
                    self._ser.write(request)
                    self._last_query = time.monotonic()
                    data = bytearray()
                    end = time.monotonic() + timeout
                    while len(data) < need and time.monotonic() < end:
                        data += self._ser.read(need - len(data))
                    time.sleep(0)
                    extra = self._ser.in_waiting
            except Exception as exc:                # noqa: BLE001 - any I/O failure
                err = RobotError(f"lost the serial link to {self.port}: {exc}")
                self._set_fault(err, stop=True)
                raise err from None
            if len(data) == need and not extra:
                return self._update(oi.decode_packets(SENSOR_IDS, bytes(data)))
        err = RobotError(f"no valid reply to a sensor query from {self.port} in 3 tries: "
                         "lost the link; tried to stop the robot")
        self._set_fault(err, stop=True)
        raise err

    def _query_lockstep(self, deadline: float) -> SensorState | None:
        """:meth:`_query` in lockstep: the clock moves to the next sensor period, then the
        query is asked and answered with the clock standing still."""
        need = oi.reply_size(SENSOR_IDS)
        request = oi.encode_query_list(SENSOR_IDS)
        for _ in range(3):
            due = self._last_query + self.spec.sensor_period
            if due > deadline:
                self._advance(deadline)
                return None
            while self.clock() < due - 1e-12:
                self._advance(due)
            self._flush_input()
            self._write(request)
            self._last_query = self.clock()
            data = self._read_until(self._advance(self.clock()))
            if len(data) == need:
                return self._update(oi.decode_packets(SENSOR_IDS, data))
        err = RobotError(f"no valid reply to a sensor query from {self.port} in 3 tries: "
                         "lost the link; tried to stop the robot")
        self._set_fault(err, stop=True)
        raise err

    def _advance(self, until: float) -> int:
        """Lockstep: move the emulated clock towards ``until`` (at most one sensor period);
        returns the bytes the emulator has written by then. A gone emulator is a lost link."""
        try:
            return self._ls.advance(self._tx, until)
        except LockstepClosed as exc:
            err = RobotError(f"lost the link to {self.port}: {exc}")
            self._set_fault(err)
            raise err from None

    def _next_state_lockstep(self, after: int | None, deadline: float) -> SensorState | None:
        """:meth:`_next_state` in stream mode and lockstep: read what the emulator sent, and
        move its clock to the next frame until a new reading or ``deadline`` comes."""
        while True:
            with self._cv:
                self._cv.wait_for(lambda: self._rx >= self._ls.robot_bytes or
                                  self._fault is not None, timeout=self._ls.wall_timeout)
                if self._fault is not None:
                    raise self._fault
                if self._rx < self._ls.robot_bytes:
                    err = RobotError(f"lost the link to {self.port}: the bytes sent did not "
                                     "arrive")
                    self._fault = err
                    raise err
                st = self._state
                self._last_call = self.clock()
                if st is not None and (after is None or st.seq > after):
                    return st
            now = self.clock()
            if now - self._last_valid > self.link_timeout:
                self._set_fault(RobotError(
                    f"no valid sensor data from {self.port} for {now - self._last_valid:.2f} s "
                    "of robot time: lost the link; tried to stop the robot"), stop=True)
                raise self._fault
            if now >= deadline:
                return None
            self._advance(min(deadline, self._ls.next_frame))

    def _next_state(self, after: int | None, deadline: float, check: bool = True
                    ) -> SensorState | None:
        """The next reading newer than ``after`` (None: any), or None once the robot clock
        passes ``deadline``. Raises the pending RobotError, if any."""
        with self._cv:
            self._last_call = self.clock()
        if self.sensing == "query":
            if self.clock() >= deadline:
                return None
            if check:
                self._raise_fault()
            st = self._query(deadline)
            self._raise_fault()
            return st
        if self._ls is not None:
            return self._next_state_lockstep(after, deadline)
        with self._cv:
            while True:
                if self._fault is not None:
                    raise self._fault
                st = self._state
                if st is not None and (after is None or st.seq > after):
                    self._last_call = self.clock()
                    return st
                left = (deadline - self.clock()) / self.time_scale
                if left <= 0:
                    return None
                self._cv.wait(min(left, 0.05))

    def _fresh(self, n: int = 1) -> SensorState:
        """A reading taken after this call (the ``n``-th one; the first may have been in
        flight already)."""
        st = self._state
        seq = None if st is None else st.seq
        limit = self.clock() + max(1.0, self.link_timeout * 2)
        for _ in range(n):
            st = self._next_state(seq, limit)
            if st is None:
                err = RobotError(f"no sensor data from {self.port}: lost the link")
                self._set_fault(err, stop=True)
                raise err
            seq = st.seq
        return st

    # ------------------------------------------------------------------ Robot interface
    def drive(self, speed: float) -> None:
        speed = float(speed)
        if not math.isfinite(speed) or abs(speed) > self.spec.max_wheel_speed + 1e-12:
            raise UserError(f"speed {speed:g} m/s is beyond the robot's "
                            f"{self.spec.max_wheel_speed:g} m/s wheel limit.")
        self._drive_direct(speed, speed)

    def stop(self) -> None:
        """Stop both wheels (best effort: never raises, the link may be gone)."""
        if self._ser is not None and not self._closed:
            self._send_stop()

    def bumper(self) -> tuple[bool, bool]:
        self._raise_fault()
        st = self._fresh(2 if self.sensing == "stream" else 1)
        return st.bump_left, st.bump_right

    def clock(self) -> float:
        if self._ls is not None:
            return self._ls.now()
        return (time.monotonic() - self._t0) * self.time_scale

    def wait(self, duration: float) -> None:
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
        next chance would come about this late: stopping now misses by less)."""
        return 0.7 * lag + 0.3 * max(self.clock() - st.t, 0.0)

    def encoders(self) -> tuple[int, int]:
        st = self._fresh(1)
        return st.left, st.right

    def turn(self, angle_deg: float) -> None:
        angle = float(angle_deg)
        if not math.isfinite(angle):
            raise ValueError(f"cannot turn by {angle_deg} degrees.")
        self._raise_fault()
        if abs(angle) < 1e-9:
            return
        v = self.turn_speed if angle > 0 else -self.turn_speed      # CCW: right wheel ahead
        duration = self.spec.turn_time(angle, self.turn_speed)
        try:
            if self.turn_mode == "clock":
                self._drive_direct(v, -v)
                self.wait(duration)
                return
            if self.turn_control == "predictive":
                self._turn_predictive(angle)
                return
            start = self._fresh(1)
            target = math.radians(abs(angle))
            omega = 2 * self.turn_speed / self.spec.wheel_base
            lead = omega * self.spec.sensor_period / 2     # stop half a reading early
            mpc = self.spec.metres_per_count
            self._drive_direct(v, -v)
            limit = self.clock() + 2 * duration + 1.0
            seq = start.seq
            while True:
                st = self._next_state(seq, limit)
                if st is None:
                    raise RobotError(f"a {angle:g}° turn by encoders did not finish in "
                                     f"{2 * duration + 1.0:.1f} s; stopped")
                seq = st.seq
                turned = ((st.right - start.right) - (st.left - start.left)) * mpc / \
                    self.spec.wheel_base
                if turned * math.copysign(1.0, angle) >= target - lead:
                    return
        finally:
            self.stop()

    def _turn_predictive(self, angle: float) -> None:
        """Encoder turn that tolerates a slow host (docs/readme_hardware.md, "Turns on a busy
        host"): legs that slow down near the target and stop where the angle will be when the
        stop lands; then the settled miss is measured and corrected at creep speed."""
        b, mpc = self.spec.wheel_base, self.spec.metres_per_count
        sense = 1.0 if angle > 0 else -1.0
        target = math.radians(abs(angle))
        start = self._fresh(1)

        def miss(st: SensorState) -> float:
            """[rad] still to turn in the commanded sense (negative: overshot)."""
            return target - sense * ((st.right - start.right) - (st.left - start.left)) * \
                mpc / b

        st = start
        for _ in range(1 + _TURN_CORRECTIONS):
            e = miss(st)
            if abs(e) <= math.radians(self.turn_tolerance):
                return
            way = math.copysign(1.0, e)             # +1: on towards the target, -1: back
            self._turn_leg(sense * way, miss, way, st)
            st = self._settled()

    def _turn_leg(self, sense: float, miss, way: float, st: SensorState) -> None:
        """Spin in ``sense`` (+1 CCW) until ``way * miss(reading)`` [rad] is used up: full turn
        speed far from the end, slowing linearly to creep speed within the slow zone, and a
        stop issued early by the rotation expected while it travels (the reading's age plus
        half a sensor period)."""
        b, period = self.spec.wheel_base, self.spec.sensor_period
        v_max, v_min = self.turn_speed, min(self.turn_speed, _CREEP_SPEED)
        zone = math.radians(_SLOW_ZONE_DEG)
        budget = self.spec.turn_time(math.degrees(way * miss(st)), v_max) * 2 + \
            2 * zone / (2 * v_min / b) + 1.0
        limit = self.clock() + budget
        v_cmd = 0.0
        try:
            while True:
                omega = 2 * v_cmd / b
                lead = omega * (max(self.clock() - st.t, 0.0) + period / 2)
                left = way * miss(st) - lead
                if left <= omega * period / 2:      # the next reading would come too late
                    return
                v = v_min + (v_max - v_min) * min(1.0, max(left, 0.0) / zone)
                if abs(v - v_cmd) >= 0.002:
                    self._drive_direct(sense * v, -sense * v)
                    v_cmd = v
                st = self._next_state(st.seq, limit)
                if st is None:
                    raise RobotError(f"a turn by encoders did not finish in {budget:.1f} s; "
                                     "stopped")
        finally:
            self.stop()

    def _settled(self) -> SensorState:
        """The first reading whose encoders equal the one before (at most 20 readings)."""
        prev = self._fresh(1)
        for _ in range(20):
            st = self._fresh(1)
            if (st.left, st.right) == (prev.left, prev.right):
                return st
            prev = st
        return prev

    def drive_until_bump(self, speed: float, timeout: float) -> BumpEvent:
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
        if self.emulator is None:
            return super().place(x, y, heading_deg)
        self.emulator.place(x, y, heading_deg)

    def true_pose(self) -> tuple[float, float, float] | None:
        return None if self.emulator is None else self.emulator.true_pose()

    # ------------------------------------------------------------------ teardown
    def close(self) -> None:
        """Stop the wheels, pause the stream, turn the OI off (Stop, 173) and release the
        port; idempotent and never raises."""
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
