"""Serve a CR-terminated line protocol on a pseudo-terminal or a loopback TCP port, each in a
background thread: the links of :class:`~sunlab.hardware.fake.FakeESP`.

Each line, without its ``CR``, goes to the controller's ``handle``, which returns the bytes to
send (None: nothing) or :data:`DISCONNECT` to hang up; a ``late`` fault leaves in its
``_late_s`` how many seconds late they are sent.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading

#: Returned by ``answer`` when the link must be closed.
DISCONNECT = object()


def _loop(fd: int, fake, hang_up) -> None:
    """Answer every line read from ``fd`` (a pty master or a connected socket) until the fake
    is closed, the link ends or a disconnect; then ``hang_up()``."""
    buf = b""
    try:
        while not fake._stop.is_set():
            if not select.select([fd], [], [], 0.05)[0]:
                continue
            data = os.read(fd, 4096)
            if not data:
                return
            *lines, buf = (buf + data).split(b"\r")
            for line in lines:
                reply = fake.handle(line)
                late, fake._late_s = fake._late_s, 0.0
                if reply is DISCONNECT:
                    return
                if late and reply:  # a slow controller: this reply, and what follows, late
                    fake._stop.wait(late)
                if reply:
                    os.write(fd, reply)
    except OSError:
        pass
    finally:
        hang_up()


def _start(fake, target, closer) -> None:
    """Run ``target`` in a daemon thread; the fake joins it and calls ``closer`` at its close."""
    thread = threading.Thread(target=target, name="sunlab-fake-esp", daemon=True)
    thread.start()
    fake._threads.append(thread)
    fake._closers.append(closer)


def serve_pty(fake) -> str:
    """A new pseudo-terminal served by ``fake``: its slave's path (to open as a serial port)."""
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    fds = [slave, master]

    def close() -> None:
        while fds:  # each once, whichever of the thread and the owner comes first
            with contextlib.suppress(OSError, IndexError):
                os.close(fds.pop())

    _start(fake, lambda: _loop(master, fake, close), close)
    return os.ttyname(slave)


def serve_tcp(fake, port: int = 0) -> str:
    """127.0.0.1:``port`` (0: any free one) served by ``fake``, one client at a time: its
    ``socket://`` URL."""
    server = socket.create_server(("127.0.0.1", int(port)))
    server.settimeout(0.05)

    def accept() -> None:
        with server:
            while not fake._stop.is_set():
                try:
                    conn, _ = server.accept()
                except TimeoutError:
                    continue
                except OSError:
                    return
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                _loop(conn.fileno(), fake, conn.close)

    _start(fake, accept, server.close)
    return f"socket://127.0.0.1:{server.getsockname()[1]}"
