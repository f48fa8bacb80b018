"""The server's message format: length-prefixed msgpack maps over TCP (docs/robot-api.md).

A frame is a 4-byte big-endian unsigned length N, then N bytes: one msgpack map. A request is
``{"request": "info" | "reset" | "observe" | "next_view", ...}``; a reply is
``{"ok": true, ...}`` or ``{"ok": false, "error": NAME, "message": TEXT}`` with NAME one of
:data:`ERRORS`. An array is the map ``{"dtype": "<u2", "shape": [H, W], "bytes": <bin>}``
(NumPy's dtype string, C order); object, string, void, complex and time dtypes are refused,
and nothing is ever unpickled. msgpack extension types are refused too.
"""

from __future__ import annotations

import socket
import struct
from typing import Any

import msgpack
import numpy as np

#: The frame's length prefix: 4 bytes, big-endian, unsigned.
LENGTH = struct.Struct(">I")
#: The largest message body a server accepts by default (a 4K uint16 depth image is 16 MiB).
MAX_MESSAGE_BYTES = 64 * 2**20
#: The dtype kinds an array may have: bool, signed and unsigned integers, floats.
ARRAY_KINDS = "biuf"
#: The named errors of a reply.
ERRORS = {
    "malformed": "the body is not one msgpack map with a string 'request'",
    "too_large": "the length prefix exceeds the server's maximum message size",
    "unknown_request": "'request' names no request (info, reset, observe, next_view)",
    "bad_array": "an array field is not {dtype, shape, bytes} of an allowed dtype",
    "bad_value": "a field's value is refused (its message says which and why)",
    "out_of_order": "the episode's state does not allow it (observe before reset, ...)",
    "internal": "the server failed on a valid request (its message says how)",
}


class WireError(ValueError):
    """A message the server refuses; ``code`` is one of :data:`ERRORS`."""

    def __init__(self, code: str, message: str) -> None:
        if code not in ERRORS:
            raise ValueError(f"unknown wire error code {code!r}")
        super().__init__(message)
        self.code = code


def encode_array(array: np.ndarray) -> dict[str, Any]:
    """An array as the wire's map ``{dtype, shape, bytes}`` (C order).

    Example:
        >>> encode_array(np.array([1, 2], dtype="<u2"))["dtype"]
        '<u2'
    """
    array = np.asarray(array)
    if array.dtype.kind not in ARRAY_KINDS:
        raise WireError("bad_array", f"dtype {array.dtype} is not sent (allowed kinds: bool, "
                                     "integers, floats)")
    array = np.ascontiguousarray(array)
    return {"dtype": array.dtype.str, "shape": list(array.shape), "bytes": array.tobytes()}


def decode_array(value: Any, name: str) -> np.ndarray:
    """The array of a wire map, checked: its dtype allowed, its bytes the shape's size.

    Args:
        value: the map ``{"dtype", "shape", "bytes"}``.
        name: the field's name, for the error.

    Returns:
        A new, writable array.
    """
    if not isinstance(value, dict) or set(value) != {"dtype", "shape", "bytes"}:
        raise WireError("bad_array", f"{name}: an array is a map with exactly dtype, shape "
                                     "and bytes")
    dtype_text, shape, data = value["dtype"], value["shape"], value["bytes"]
    if not isinstance(dtype_text, str) or not isinstance(data, bytes) or \
            not isinstance(shape, list) or \
            not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape):
        raise WireError("bad_array", f"{name}: dtype must be a string, shape a list of "
                                     "non-negative integers, bytes binary")
    try:
        dtype = np.dtype(dtype_text)
    except TypeError as exc:
        raise WireError("bad_array", f"{name}: dtype {dtype_text!r} is not a NumPy dtype"
                        ) from exc
    if dtype.kind not in ARRAY_KINDS or dtype.fields is not None or dtype.subdtype is not None:
        raise WireError("bad_array", f"{name}: dtype {dtype_text!r} is refused (allowed "
                                     "kinds: bool, integers, floats)")
    expected = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    if expected != len(data):
        raise WireError("bad_array", f"{name}: shape {shape} of {dtype_text} needs {expected} "
                                     f"bytes, got {len(data)}")
    return np.frombuffer(data, dtype=dtype).reshape(shape).copy()


def _no_extensions(code: int, data: bytes) -> Any:
    raise WireError("malformed", f"msgpack extension type {code} is refused")


def unpack(body: bytes) -> dict[str, Any]:
    """A request's body as a map, or a :class:`WireError` ("malformed")."""
    try:
        message = msgpack.unpackb(body, raw=False, strict_map_key=True,
                                  ext_hook=_no_extensions)
    except WireError:
        raise
    except Exception as exc:  # msgpack raises several types for broken input
        raise WireError("malformed", f"the body is not msgpack: {exc}") from exc
    if not isinstance(message, dict):
        raise WireError("malformed", f"a message is a map, got {type(message).__name__}")
    return message


def pack(message: dict[str, Any]) -> bytes:
    """A message as one frame: the length prefix, then the msgpack body."""
    body = msgpack.packb(message, use_bin_type=True)
    return LENGTH.pack(len(body)) + body


def receive_exactly(sock: socket.socket, count: int) -> bytes | None:
    """``count`` bytes from ``sock``, or None when the peer closed before sending any;
    a close in the middle raises ``ConnectionError``."""
    chunks, got = [], 0
    while got < count:
        chunk = sock.recv(min(count - got, 2**20))
        if not chunk:
            if got == 0:
                return None
            raise ConnectionError(f"the peer closed after {got} of {count} bytes")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def discard(sock: socket.socket, count: int) -> None:
    """Read and drop ``count`` bytes (an oversized message's body), a MiB at a time."""
    left = count
    while left:
        chunk = sock.recv(min(left, 2**20))
        if not chunk:
            raise ConnectionError(f"the peer closed with {left} bytes of a message unread")
        left -= len(chunk)


def receive_frame(sock: socket.socket, max_bytes: int = MAX_MESSAGE_BYTES
                  ) -> bytes | None:
    """One frame's body, or None at a clean close. An oversized body is read, dropped and
    reported as a :class:`WireError` ("too_large"), so the stream stays in step."""
    prefix = receive_exactly(sock, LENGTH.size)
    if prefix is None:
        return None
    (length,) = LENGTH.unpack(prefix)
    if length > max_bytes:
        discard(sock, length)
        raise WireError("too_large", f"a message of {length} bytes exceeds the maximum of "
                                     f"{max_bytes}")
    body = receive_exactly(sock, length)
    if body is None:
        raise ConnectionError(f"the peer closed before a message's {length} bytes")
    return body


def error_reply(code: str, message: str) -> dict[str, Any]:
    """The reply naming an error."""
    return {"ok": False, "error": code, "message": message}
