"""The OI emulator's end of the serial link: a pseudo-terminal master, or a TCP listener
with one client (what a pyserial ``socket://`` URL connects to).
"""

from __future__ import annotations

import os
import socket
import tty

from envs import UserError

__all__ = ["Transport"]


class Transport:
    """The emulator's end of the link: a pty master or a TCP listener with one client."""

    def __init__(self, kind: str, host: str, port: int) -> None:
        self.kind = kind
        self.client: socket.socket | None = None
        self.connections = 0
        if kind == "pty":
            self.master, self.slave = os.openpty()
            tty.setraw(self.slave)          # no echo, no line editing: a plain byte pipe
            os.set_blocking(self.master, False)
            self.url = os.ttyname(self.slave)
            self.listener = None
        elif kind == "tcp":
            self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                self.listener.bind((host, int(port)))
            except OSError as exc:
                self.listener.close()
                raise UserError(f"cannot listen on {host}:{port}: {exc.strerror}.") from None
            self.listener.listen(1)
            self.listener.setblocking(False)
            h, p = self.listener.getsockname()[:2]
            self.url = f"socket://{h}:{p}"
            self.master = self.slave = None
        else:
            raise UserError(f"transport must be 'pty' or 'tcp', got {kind!r}.")

    def fds(self) -> list:
        """The file descriptors the emulator's select loop waits on."""
        if self.kind == "pty":
            return [self.master]
        return [self.listener] + ([self.client] if self.client is not None else [])

    def read(self, ready) -> bytes:
        """Bytes that arrived (accepting a new client on the way)."""
        data = b""
        if self.kind == "pty":
            if self.master in ready:
                try:
                    data = os.read(self.master, 4096)
                except (BlockingIOError, OSError):
                    data = b""
            return data
        if self.listener in ready:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                conn = None
            if conn is not None:
                if self.client is not None:
                    self.client.close()
                conn.setblocking(False)
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.client = conn
                self.connections += 1
        if self.client is not None and self.client in ready:
            try:
                data = self.client.recv(4096)
                if not data:                     # the controller hung up
                    self.client.close()
                    self.client = None
            except BlockingIOError:
                data = b""
            except OSError:
                self.client.close()
                self.client = None
                data = b""
        return data

    def write(self, data: bytes) -> int:
        """Send without blocking: bytes nobody reads are lost, as on a serial line. Returns
        the number of bytes sent.
        """
        if not data:
            return 0
        try:
            if self.kind == "pty":
                return os.write(self.master, data)
            if self.client is not None:
                return self.client.send(data)
        except (BlockingIOError, OSError):
            pass
        return 0

    def close(self) -> None:
        """Close the pty or the sockets (idempotent)."""
        for fd in (self.master, self.slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        for s in (self.client, self.listener):
            if s is not None:
                s.close()
        self.master = self.slave = self.client = self.listener = None
