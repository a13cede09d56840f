"""A loopback CAN hub for processes without SocketCAN: a small socketcand-protocol server (python-can's
`interface='socketcand'` client) plus optional slcan pseudo-terminals (python-can's `interface='slcan'`, the
protocol of USB-CAN adapters such as CANable).

Every frame one endpoint sends is delivered to all the OTHER endpoints (a CAN bus without local echo). Writes are
non-blocking; each endpoint has a bounded queue and a full queue drops its OLDEST frame (like a CAN controller
RX-FIFO overrun), counted per endpoint in `stats()`. Listens on 127.0.0.1 only; never multicast.

Protocol subset (socketcand rawmode): server `< hi >`; client `< open CH >` -> `< ok >`; `< rawmode >` -> `< ok >`;
client `< send ID LEN B0 B1 ... >`; server `< frame ID SEC.USEC HEXDATA >`.
"""
from __future__ import annotations

import logging
import os
import selectors
import socket
import threading
import time
import tty
from collections import deque

import can

log = logging.getLogger(__name__)


class _Endpoint:
    def __init__(self, hub, kind: str, name: str, max_queue: int):
        self.hub = hub
        self.kind = kind
        self.name = name
        self.inbuf = b""
        self.out: deque[bytes] = deque()
        self.partial = b""
        self.max_queue = max_queue
        self.dropped = 0
        self.rx_frames = 0
        self.tx_frames = 0
        self.active = kind in ("slcan", "local")   # socketcand: only after rawmode

    def queue(self, data: bytes) -> None:
        if len(self.out) >= self.max_queue:
            self.out.popleft()
            self.dropped += 1
        self.out.append(data)
        self.tx_frames += 1


class CanHub:
    def __init__(self, host: str = "127.0.0.1", port: int = 0, max_queue: int = 4096):
        if host not in ("127.0.0.1", "localhost", "::1"):
            raise ValueError("the hub serves the loopback interface only")
        self.max_queue = max_queue
        self.sel = selectors.DefaultSelector()
        self.lsock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.lsock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.lsock.bind(("127.0.0.1", port))
        self.lsock.listen(16)
        self.lsock.setblocking(False)
        self.host, self.port = self.lsock.getsockname()
        self.sel.register(self.lsock, selectors.EVENT_READ, None)
        self.endpoints: dict[int, _Endpoint] = {}
        self.frames = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        self.sel.register(self._wake_r, selectors.EVENT_READ, "wake")
        self._ptys: list[tuple[int, int]] = []
        self._lock = threading.RLock()
        self._next_local = -1

    # ------------------------------------------------------------------ in-process endpoint
    def local_bus(self, name: str = "local") -> "LocalHubBus":
        """A python-can bus attached to the hub inside this process (no TCP, no text protocol): what js2-sim's own
        drives use, so the simulator process spends its time on the drives, not on the transport."""
        with self._lock:
            key = self._next_local
            self._next_local -= 1
            ep = _Endpoint(self, "local", name, self.max_queue)
            bus = LocalHubBus(self, key, ep)
            ep.bus = bus
            self.endpoints[key] = ep
        return bus

    def inject(self, key: int, cid: int, ext: bool, payload: bytes, error: bool = False) -> None:
        with self._lock:
            ep = self.endpoints.get(key)
            if ep is not None:
                ep.rx_frames += 1
            self._broadcast(key, cid, ext, payload, error)

    # ------------------------------------------------------------------ endpoints
    def add_slcan_pty(self) -> str:
        """A pseudo-terminal that speaks slcan (Lawicel); returns its path for `interface='slcan', channel=PATH`."""
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        path = os.ttyname(slave)
        ep = _Endpoint(self, "slcan", path, self.max_queue)
        self.endpoints[master] = ep
        self._ptys.append((master, slave))
        self.sel.register(master, selectors.EVENT_READ, ep)
        return path

    def stats(self) -> dict:
        return {"frames": self.frames,
                "endpoints": [{"name": e.name, "kind": e.kind, "rx": e.rx_frames, "tx": e.tx_frames,
                               "dropped": e.dropped} for e in self.endpoints.values()]}

    # ------------------------------------------------------------------ loop
    def start(self) -> "CanHub":
        self._thread = threading.Thread(target=self.serve_forever, name="js2-can-hub", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        with self._lock:
            for fd in list(self.endpoints):
                self._close(fd)
        for m, s in self._ptys:
            for fd in (s,):
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.lsock.close()

    def serve_forever(self) -> None:
        while not self._stop.is_set():
            for key, mask in self.sel.select(timeout=0.5):
                if key.data is None:
                    with self._lock:
                        self._accept()
                elif key.data == "wake":
                    try:
                        os.read(self._wake_r, 64)
                    except OSError:
                        pass
                else:
                    fd = key.fd if isinstance(key.fileobj, int) else key.fileobj.fileno()
                    with self._lock:
                        if mask & selectors.EVENT_READ:
                            self._read(fd)
                        if mask & selectors.EVENT_WRITE and fd in self.endpoints:
                            self._flush(fd)

    def _accept(self) -> None:
        try:
            conn, addr = self.lsock.accept()
        except BlockingIOError:
            return
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        # a small kernel buffer keeps frames in OUR bounded queue (drop-oldest) instead of piling up stale in TCP
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 64 * 1024)
        conn.setblocking(False)
        ep = _Endpoint(self, "socketcand", f"{addr[0]}:{addr[1]}", self.max_queue)
        ep.sock = conn
        fd = conn.fileno()
        self.endpoints[fd] = ep
        self.sel.register(conn, selectors.EVENT_READ, ep)
        self._direct(fd, b"< hi >")

    def _direct(self, fd, data: bytes) -> None:
        """A protocol reply, sent on its own (python-can's client reads it with a single recv)."""
        ep = self.endpoints[fd]
        ep.out.append(data)
        self._flush(fd)
        time.sleep(0.002)   # keep the reply in its own TCP segment

    def _close(self, fd) -> None:
        ep = self.endpoints.pop(fd, None)
        if ep is None or ep.kind == "local":
            return
        try:
            self.sel.unregister(ep.sock if ep.kind == "socketcand" else fd)
        except (KeyError, ValueError):
            pass
        if ep.kind == "socketcand":
            ep.sock.close()
        else:
            try:
                os.close(fd)
            except OSError:
                pass

    def _read(self, fd) -> None:
        ep = self.endpoints.get(fd)
        if ep is None:
            return
        try:
            data = ep.sock.recv(65536) if ep.kind == "socketcand" else os.read(fd, 65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            if ep.kind == "socketcand":
                self._close(fd)
            return
        ep.inbuf += data
        if ep.kind == "socketcand":
            self._parse_socketcand(fd, ep)
        else:
            self._parse_slcan(fd, ep)

    def _parse_socketcand(self, fd, ep) -> None:
        buf = ep.inbuf
        while True:
            a = buf.find(b"<")
            b = buf.find(b">", a + 1)
            if a < 0 or b < 0:
                break
            parts = buf[a + 1:b].split()
            buf = buf[b + 1:]
            if not parts:
                continue
            cmd = parts[0]
            if cmd == b"send" and len(parts) >= 3:
                try:
                    cid = int(parts[1], 16)
                    n = int(parts[2], 16)
                    payload = bytes(int(x, 16) for x in parts[3:3 + n])
                except ValueError:
                    continue
                ep.rx_frames += 1
                self._broadcast(fd, cid, len(parts[1]) > 3, payload)
            elif cmd == b"open":
                self._direct(fd, b"< ok >")
            elif cmd == b"rawmode":
                self._direct(fd, b"< ok >")
                ep.active = True
            elif cmd == b"echo":
                self._direct(fd, b"< echo >")
        ep.inbuf = buf

    def _parse_slcan(self, fd, ep) -> None:
        buf = ep.inbuf
        while True:
            k = buf.find(b"\r")
            if k < 0:
                break
            line, buf = buf[:k].decode("ascii", "replace"), buf[k + 1:]
            if not line:
                continue
            c = line[0]
            try:
                if c in "tT":
                    nid = 3 if c == "t" else 8
                    cid = int(line[1:1 + nid], 16)
                    n = int(line[1 + nid])
                    payload = bytes.fromhex(line[2 + nid:2 + nid + 2 * n])
                    ep.rx_frames += 1
                    self._broadcast(fd, cid, c == "T", payload)
                    continue
            except ValueError:
                pass
            if c == "V":
                ep.out.append(b"V1013\r")
            elif c == "N":
                ep.out.append(b"NJS02\r")
            else:             # O, C, S<n>, L, ...: acknowledge
                ep.out.append(b"\r")
            self._flush(fd)
        ep.inbuf = buf

    def _broadcast(self, src_fd, cid: int, ext: bool, payload: bytes, error: bool = False) -> None:
        self.frames += 1
        ts = time.time()
        sc = None
        sl = None
        for fd, ep in list(self.endpoints.items()):
            if fd == src_fd or not ep.active:
                continue
            if ep.kind == "local":
                ep.bus._deliver(cid, ext, payload, ts, error)
                continue
            if ep.kind == "socketcand":
                if sc is None:
                    ids = f"{cid:08X}" if ext else f"{cid:03X}"
                    sc = (f"< error {cid & 0x1FFFFFFF:08X} {ts:.6f} >" if error else
                          f"< frame {ids} {ts:.6f} {payload.hex().upper()} >").encode()
                ep.queue(sc)
            elif error:
                continue      # slcan has no error frames
            else:
                if sl is None:
                    sl = (f"T{cid:08X}" if ext else f"t{cid:03X}") .encode() + f"{len(payload)}".encode() + \
                        payload.hex().upper().encode() + b"\r"
                ep.queue(sl)
            self._flush(fd)

    def _flush(self, fd) -> None:
        ep = self.endpoints.get(fd)
        if ep is None:
            return
        while ep.partial or ep.out:
            if not ep.partial:
                # coalesce queued frames into one write
                chunk = []
                size = 0
                while ep.out and size < 16384:
                    d = ep.out.popleft()
                    chunk.append(d)
                    size += len(d)
                ep.partial = b"".join(chunk)
            try:
                n = ep.sock.send(ep.partial) if ep.kind == "socketcand" else os.write(fd, ep.partial)
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                self._close(fd)
                return
            ep.partial = ep.partial[n:]
            if ep.partial:
                break
        want = selectors.EVENT_READ | (selectors.EVENT_WRITE if (ep.partial or ep.out) else 0)
        try:
            self.sel.modify(ep.sock if ep.kind == "socketcand" else fd, want, ep)
        except (KeyError, ValueError):
            pass


class LocalHubBus(can.BusABC):
    """python-can bus for an endpoint of a CanHub in the same process (see CanHub.local_bus)."""

    def __init__(self, hub: CanHub, key: int, ep: _Endpoint, **kwargs):
        self.hub = hub
        self.key = key
        self.ep = ep
        self._q: deque = deque()
        self._cv = threading.Condition()
        self.channel_info = f"js2 hub (in-process endpoint of 127.0.0.1:{hub.port})"
        super().__init__(channel="js2-hub-local", **kwargs)

    def _deliver(self, cid, ext, payload, ts, error) -> None:
        with self._cv:
            if len(self._q) >= self.ep.max_queue:
                self._q.popleft()
                self.ep.dropped += 1
            self._q.append((cid, ext, payload, ts, error))
            self.ep.tx_frames += 1
            self._cv.notify()

    def send(self, msg: can.Message, timeout=None) -> None:
        self.hub.inject(self.key, msg.arbitration_id, msg.is_extended_id, bytes(msg.data), msg.is_error_frame)

    def _recv_internal(self, timeout):
        with self._cv:
            if not self._q:
                self._cv.wait(timeout)
            if not self._q:
                return None, False
            cid, ext, payload, ts, error = self._q.popleft()
        return can.Message(arbitration_id=cid, is_extended_id=ext, data=payload, timestamp=ts, is_rx=True,
                           is_error_frame=error), False

    def shutdown(self) -> None:
        with self.hub._lock:
            self.hub.endpoints.pop(self.key, None)
        super().shutdown()
