"""A local server around one :class:`ActiveRecognizer` (``rapomdp serve``) and its Python client.

The server binds to 127.0.0.1 by default and serves one client at a time, one request after
another, in the format of :mod:`rapomdp.robot_api.wire`. A refused message gets a named error
reply and the connection stays open; a client that disconnects, mid-episode or not, leaves the
server waiting for the next, which starts with no episode (it must ``reset``).

Requests and their replies (arrays as :func:`~rapomdp.robot_api.wire.encode_array` maps):

- ``{"request": "info"}`` → the method, classes, X_rho's camera centres and poses, reachable
  viewpoints, the object's centroid, the camera mount, the step budget.
- ``{"request": "reset", "seed": int | nil}`` → ``{"ok": true}``.
- ``{"request": "observe", "depth": array, "camera_pose": array (4, 4) | "viewpoint": int,
  "intrinsics": {"fx", "fy", "cx", "cy"} | nil}`` → the :class:`Observation`'s fields.
- ``{"request": "next_view"}`` → the :class:`NextView`'s fields.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable
from dataclasses import fields
from typing import Any

import numpy as np

from rapomdp.robot_api.recognizer import (
    ActiveRecognizer,
    NextView,
    Observation,
    OutOfOrderError,
)
from rapomdp.robot_api.wire import (
    MAX_MESSAGE_BYTES,
    WireError,
    decode_array,
    encode_array,
    error_reply,
    pack,
    receive_frame,
    unpack,
)

#: The address the server binds to unless told otherwise: this machine only.
DEFAULT_HOST = "127.0.0.1"
#: The port ``rapomdp serve`` listens on by default.
DEFAULT_PORT = 8765
#: Seconds a connected client may stay silent before the server drops it.
IDLE_TIMEOUT_S = 300.0


def to_message(answer: Observation | NextView) -> dict[str, Any]:
    """An answer's fields as a reply (arrays encoded)."""
    out: dict[str, Any] = {"ok": True}
    for item in fields(answer):
        value = getattr(answer, item.name)
        out[item.name] = encode_array(value) if isinstance(value, np.ndarray) else value
    return out


def from_message(kind: type[Observation] | type[NextView], reply: dict[str, Any]
                 ) -> Observation | NextView:
    """The answer a reply carries (the inverse of :func:`to_message`)."""
    values = {}
    for item in fields(kind):
        value = reply[item.name]
        values[item.name] = decode_array(value, item.name) if isinstance(value, dict) else value
    return kind(**values)


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return encode_array(value)
    return value


class Handler:
    """The requests of one server: each maps a request to a reply, or raises a named error."""

    def __init__(self, recognizer: ActiveRecognizer) -> None:
        self.recognizer = recognizer
        self.requests: dict[str, Callable[[dict[str, Any]], dict[str, Any]]] = {
            "info": self.info, "reset": self.reset, "observe": self.observe,
            "next_view": self.next_view}

    def answer(self, body: bytes) -> dict[str, Any]:
        """The reply to one request's body (every failure a named error reply)."""
        try:
            message = unpack(body)
            name = message.get("request")
            if not isinstance(name, str):
                raise WireError("malformed", "a request needs the string field 'request'")
            if name not in self.requests:
                raise WireError("unknown_request", f"request {name!r} is not one of "
                                f"{', '.join(self.requests)}")
            return self.requests[name](message)
        except WireError as exc:
            return error_reply(exc.code, str(exc))
        except OutOfOrderError as exc:
            return error_reply("out_of_order", f"{exc.code}: {exc}")
        except (ValueError, TypeError) as exc:
            return error_reply("bad_value", str(exc))
        except Exception as exc:  # the server stays up whatever a request does
            return error_reply("internal", f"{type(exc).__name__}: {exc}")

    def forget(self) -> None:
        """A new client: no episode until it resets."""
        self.recognizer.forget()

    def info(self, message: dict[str, Any]) -> dict[str, Any]:
        return {"ok": True, **{k: _plain(v) for k, v in self.recognizer.info().items()}}

    def reset(self, message: dict[str, Any]) -> dict[str, Any]:
        seed = message.get("seed")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)
                                 or seed < 0):
            raise WireError("bad_value", f"seed must be a non-negative integer or nil, got "
                                         f"{seed!r}")
        self.recognizer.reset(seed=seed)
        return {"ok": True}

    def observe(self, message: dict[str, Any]) -> dict[str, Any]:
        if "depth" not in message:
            raise WireError("bad_value", "observe needs 'depth'")
        depth = decode_array(message["depth"], "depth")
        pose = message.get("camera_pose")
        viewpoint = message.get("viewpoint")
        if viewpoint is not None and (isinstance(viewpoint, bool)
                                      or not isinstance(viewpoint, int)):
            raise WireError("bad_value", f"viewpoint must be an integer, got {viewpoint!r}")
        intrinsics = message.get("intrinsics")
        if intrinsics is not None and not isinstance(intrinsics, dict):
            raise WireError("bad_value", "intrinsics must be a map {fx, fy, cx, cy}")
        camera_pose = None if pose is None else decode_array(pose, "camera_pose")
        return to_message(self.recognizer.observe(depth, camera_pose, intrinsics, viewpoint))

    def next_view(self, message: dict[str, Any]) -> dict[str, Any]:
        return to_message(self.recognizer.next_view())


class RecognizerServer:
    """Serves one :class:`ActiveRecognizer` on a TCP port, one client at a time.

    Args:
        recognizer: the object every request drives.
        host: the address to bind (default: this machine only).
        port: the port (0: one the system picks; :attr:`address` tells it).
        max_message_bytes: the largest request body accepted.
        idle_timeout_s: how long a connected client may stay silent.

    Example (a server in a thread, on a port the system picks)::

        server = RecognizerServer(ActiveRecognizer.load("runs/demo"), port=0)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        with RecognizerClient(*server.address) as client:
            client.info()["method"]  # 'ra'
    """

    def __init__(self, recognizer: ActiveRecognizer, host: str = DEFAULT_HOST,
                 port: int = DEFAULT_PORT, max_message_bytes: int = MAX_MESSAGE_BYTES,
                 idle_timeout_s: float = IDLE_TIMEOUT_S) -> None:
        self.handler = Handler(recognizer)
        self.max_message_bytes = int(max_message_bytes)
        self.idle_timeout_s = float(idle_timeout_s)
        self._socket = socket.create_server((host, port))
        self._socket.settimeout(0.2)  # checks for shutdown between accepts
        self._stop = threading.Event()

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) the server listens on."""
        host, port = self._socket.getsockname()[:2]
        return str(host), int(port)

    def serve_forever(self) -> None:
        """Accept clients one after another until :meth:`shutdown`."""
        try:
            while not self._stop.is_set():
                try:
                    connection, _ = self._socket.accept()
                except TimeoutError:
                    continue
                with connection:
                    self.serve_client(connection)
        finally:
            self._socket.close()

    def serve_client(self, connection: socket.socket) -> None:
        """Every request of one client until it disconnects (or stays silent too long)."""
        self.handler.forget()
        connection.settimeout(self.idle_timeout_s)
        while not self._stop.is_set():
            try:
                body = receive_frame(connection, self.max_message_bytes)
            except WireError as exc:
                reply = error_reply(exc.code, str(exc))
            except (ConnectionError, TimeoutError, OSError):
                break
            else:
                if body is None:
                    break
                reply = self.handler.answer(body)
            try:
                connection.sendall(pack(reply))
            except OSError:
                break
        self.handler.forget()

    def shutdown(self) -> None:
        """Stop after the current client (within 0.2 s when none is connected)."""
        self._stop.set()


class RemoteError(RuntimeError):
    """An error reply: ``code`` is its name (:data:`rapomdp.robot_api.wire.ERRORS`)."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(f"{code}: {message}")
        self.code = code


class RecognizerClient:
    """The Python client of :class:`RecognizerServer`; its answers are the object's types.

    Args:
        host: the server's address.
        port: its port.
        timeout_s: how long to wait for a reply.
    """

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT,
                 timeout_s: float = 60.0) -> None:
        self._socket = socket.create_connection((host, port), timeout=timeout_s)

    def request(self, message: dict[str, Any]) -> dict[str, Any]:
        """Send one request, return its reply (an error reply raises :class:`RemoteError`)."""
        self._socket.sendall(pack(message))
        body = receive_frame(self._socket, 2**31)
        if body is None:
            raise ConnectionError("the server closed the connection")
        reply = unpack(body)
        if not reply.get("ok"):
            raise RemoteError(str(reply.get("error")), str(reply.get("message")))
        return reply

    def info(self) -> dict[str, Any]:
        """The server's :meth:`ActiveRecognizer.info` (arrays decoded)."""
        reply = self.request({"request": "info"})
        return {k: decode_array(v, k) if isinstance(v, dict) else v
                for k, v in reply.items() if k != "ok"}

    def reset(self, seed: int | None = None) -> None:
        """:meth:`ActiveRecognizer.reset` on the server."""
        self.request({"request": "reset", "seed": seed})

    def observe(self, depth: np.ndarray, camera_pose: np.ndarray | None = None,
                intrinsics: dict[str, float] | None = None,
                viewpoint: int | None = None) -> Observation:
        """:meth:`ActiveRecognizer.observe` on the server."""
        message: dict[str, Any] = {"request": "observe", "depth": encode_array(depth)}
        if camera_pose is not None:
            message["camera_pose"] = encode_array(np.asarray(camera_pose, dtype=np.float64))
        if viewpoint is not None:
            message["viewpoint"] = int(viewpoint)
        if intrinsics is not None:
            message["intrinsics"] = {k: float(v) for k, v in intrinsics.items()}
        answer = from_message(Observation, self.request(message))
        assert isinstance(answer, Observation)
        return answer

    def next_view(self) -> NextView:
        """:meth:`ActiveRecognizer.next_view` on the server."""
        answer = from_message(NextView, self.request({"request": "next_view"}))
        assert isinstance(answer, NextView)
        return answer

    def close(self) -> None:
        self._socket.close()

    def __enter__(self) -> RecognizerClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
