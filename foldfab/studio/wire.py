"""The studio's wire: a refused request (:class:`ApiError`), an answer (:class:`Response`), the
binary answer format (:func:`pack`, :func:`unpack`: a JSON header and aligned arrays, so the browser
reads a design's arrays without parsing numbers) and the checked reading of request fields."""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

MAGIC = b"FFS1"


class ApiError(Exception):
    """A request the studio refuses: HTTP ``status`` with ``message`` and extra JSON fields."""

    def __init__(self, message: str, status: int = 400, **extra: Any):
        super().__init__(message)
        self.status = status
        self.extra = extra


@dataclass(frozen=True)
class Response:
    """What the server sends back."""

    status: int
    content_type: str
    body: bytes

    @classmethod
    def json(cls, data: dict, status: int = 200) -> Response:
        return cls(status, "application/json", json.dumps(data, allow_nan=False).encode())


def pack(header: dict, arrays: dict[str, np.ndarray]) -> bytes:
    """``MAGIC``, header length (u32), JSON header (``arrays``: dtype, shape, offset), 8-byte aligned arrays."""
    meta, chunks, offset = {}, [], 0
    for name, array in arrays.items():
        array = np.ascontiguousarray(array, dtype=array.dtype.newbyteorder("<"))
        data = array.tobytes()
        meta[name] = {"dtype": array.dtype.str[1:], "shape": list(array.shape), "offset": offset}
        chunks.append(data + b"\0" * (-len(data) % 8))
        offset += len(data) + (-len(data) % 8)
    head = json.dumps({**header, "arrays": meta}, allow_nan=False).encode()
    head += b" " * (-(len(head) + 8) % 8)
    return MAGIC + struct.pack("<I", len(head)) + head + b"".join(chunks)


def unpack(data: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and arrays of :func:`pack` (for tests and tools)."""
    if data[:4] != MAGIC:
        raise ValueError("not a studio design")
    (length,) = struct.unpack("<I", data[4:8])
    header = json.loads(data[8:8 + length])
    start = 8 + length
    arrays = {name: np.frombuffer(data, np.dtype("<" + m["dtype"]), int(np.prod(m["shape"])), start + m["offset"])
              .reshape(m["shape"]) for name, m in header["arrays"].items()}
    return header, arrays


_REQUIRED = object()


def field_of(body: dict, key: str, kind: type | tuple[type, ...], default: Any = _REQUIRED) -> Any:
    """``body[key]`` checked to be of ``kind`` (a string at most 4096 characters), else ``default``;
    a missing required field or a wrong kind is an :class:`ApiError`."""
    if key not in body:
        if default is _REQUIRED:
            raise ApiError(f"request: missing field {key!r}")
        return default
    value = body[key]
    if isinstance(value, bool) and bool not in (kind if isinstance(kind, tuple) else (kind,)):
        raise ApiError(f"request: {key!r} must be {_kind_name(kind)}, got a boolean")
    if not isinstance(value, kind):
        raise ApiError(f"request: {key!r} must be {_kind_name(kind)}, got {type(value).__name__}")
    if isinstance(value, str) and len(value) > 4096:
        raise ApiError(f"request: {key!r} is longer than 4096 characters")
    return value


def _kind_name(kind) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join({dict: "an object", str: "a string", bool: "true or false", int: "a whole number",
                        float: "a number", list: "a list"}[k] for k in kinds)


def number_of(body: dict, key: str, default: int, low: int, high: int) -> int:
    """A whole number field from ``low`` to ``high``."""
    value = field_of(body, key, int, default)
    if not low <= value <= high:
        raise ApiError(f"request: {key!r} must be from {low} to {high}, got {value}")
    return value
