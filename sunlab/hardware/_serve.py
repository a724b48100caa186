"""Serve a CR-terminated line protocol on a pseudo-terminal or a loopback TCP port, each in a
background thread: the links of :class:`~sunlab.hardware.fake.FakeESP`.

``answer(line)`` gets each line without its ``CR`` and returns ``(reply, late_s)``: the bytes to
send (None: nothing), sent ``late_s`` seconds late, or :data:`DISCONNECT` to hang up.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import threading

#: Returned by ``answer`` when the link must be closed.
DISCONNECT = object()


def _loop(fd: int, answer, stop: threading.Event, hang_up) -> None:
    """Answer every line read from ``fd`` (a pty master or a connected socket) until ``stop``,
    the link's end or a disconnect; then ``hang_up()``."""
    buf = b""
    try:
        while not stop.is_set():
            if not select.select([fd], [], [], 0.05)[0]:
                continue
            data = os.read(fd, 4096)
            if not data:
                return
            *lines, buf = (buf + data).split(b"\r")
            for line in lines:
                reply, late = answer(line)
                if reply is DISCONNECT:
                    return
                if late and reply:  # a slow controller: this reply, and what follows, late
                    stop.wait(late)
                if reply:
                    os.write(fd, reply)
    except OSError:
        pass
    finally:
        hang_up()


def _thread(target) -> threading.Thread:
    thread = threading.Thread(target=target, name="sunlab-fake-esp", daemon=True)
    thread.start()
    return thread


def serve_pty(answer, stop: threading.Event):
    """A new pseudo-terminal served by ``answer``: its slave's path (to open as a serial
    port), the thread, and the function that closes the terminal."""
    import tty

    master, slave = os.openpty()
    tty.setraw(slave)
    fds = [slave, master]

    def close() -> None:
        while fds:  # each once, whichever of the thread and the owner comes first
            with contextlib.suppress(OSError, IndexError):
                os.close(fds.pop())

    return os.ttyname(slave), _thread(lambda: _loop(master, answer, stop, close)), close


def serve_tcp(answer, stop: threading.Event, port: int = 0):
    """127.0.0.1:``port`` (0: any free one) served by ``answer``, one client at a time: its
    ``socket://`` URL, the thread, and the function that closes the server."""
    server = socket.create_server(("127.0.0.1", int(port)))
    server.settimeout(0.05)

    def accept() -> None:
        with server:
            while not stop.is_set():
                try:
                    conn, _ = server.accept()
                except TimeoutError:
                    continue
                except OSError:
                    return
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                _loop(conn.fileno(), answer, stop, conn.close)

    return f"socket://127.0.0.1:{server.getsockname()[1]}", _thread(accept), server.close
