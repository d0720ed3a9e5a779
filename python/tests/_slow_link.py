"""A TCP proxy in front of a served emulator that holds each chunk ``delay_s`` in each direction, as a real
line takes its time (a stop is then confirmed tens of ms after it was sent); :meth:`SlowLink.cut` makes it
drop everything both ways from then on, the connection left open (nothing the client sends is answered)."""

from __future__ import annotations

import queue
import socket
import threading
import time
from typing import Any


class SlowLink:
    def __init__(self, upstream: str, delay_s: float = 0.03) -> None:
        host, port = upstream[len("tcp://") :].rsplit(":", 1)
        self._up = (host, int(port))
        self._delay = delay_s
        self._cut = False
        self._srv = socket.socket()
        self._srv.bind(("127.0.0.1", 0))
        self._srv.listen(4)
        self.port = f"tcp://127.0.0.1:{self._srv.getsockname()[1]}"
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self._srv.accept()
            except OSError:
                return
            up = socket.create_connection(self._up)
            for a, b in ((conn, up), (up, conn)):
                a.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    def _pump(self, src: socket.socket, dst: socket.socket) -> None:
        held: "queue.Queue[Any]" = queue.Queue()

        def send() -> None:
            while (item := held.get()) is not None:
                time.sleep(max(0.0, item[0] - time.monotonic()))
                if not self._cut:
                    try:
                        dst.sendall(item[1])
                    except OSError:
                        return
            try:
                dst.shutdown(socket.SHUT_WR)
            except OSError:
                pass

        threading.Thread(target=send, daemon=True).start()
        while True:
            try:
                data = src.recv(4096)
            except OSError:
                data = b""
            if not data:
                held.put(None)
                return
            held.put((time.monotonic() + self._delay, data))

    def cut(self) -> None:
        """From now on nothing passes, either way."""
        self._cut = True

    def __enter__(self) -> "SlowLink":
        return self

    def __exit__(self, *exc: Any) -> None:
        self._srv.close()
