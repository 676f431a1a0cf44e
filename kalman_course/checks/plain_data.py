"""Plain data between the grading process and the learner's kernel: JSON, never pickle.

When ``kalman-course grade`` grades a notebook, the checks run in the grading process and
every call of a learner function crosses to the learner's kernel and back as text. This
module is that text's format, used by both sides. What can cross:

- ``None``, ``bool``, ``int``, ``float`` (NaN and ±inf included), ``str``; lists, tuples and
  dicts of those (tagged so that a tuple stays a tuple);
- numpy arrays and numpy scalars of boolean, integer, float or complex dtype (raw
  little-endian bytes in base64, so every value crosses exactly);
- instances of the course's own dataclasses (``NominalState``, ``ImuData``, ...), as their
  constructor's arguments;
- towards the kernel only: functions of the course's package (by import path), partial
  applications of them, and names of the learner's own functions;
- back from the kernel only: an exception the learner's code raised (its type's name and
  message) and, for anything else, the name of its type.

Decoding builds only exact builtin and numpy types (a ``str`` subclass or an object with
``__array__`` arrives as a plain ``str`` or array, or not at all), and the grading side
accepts no functions and no classes outside ``kalman_course``.

Every encoded object is a JSON object with a ``"~"`` key naming its kind; JSON arrays are
lists.
"""

from __future__ import annotations

import base64
import dataclasses
import functools
import importlib
import json
import math
import types
from typing import Callable

import numpy as np

#: dtypes that cross as arrays or numpy scalars (byte order fixed to little-endian).
DTYPES = frozenset(["?"] + [np.dtype(f"<{k}{n}").str for k, sizes in
                            (("i", (1, 2, 4, 8)), ("u", (1, 2, 4, 8)), ("f", (2, 4, 8)), ("c", (8, 16)))
                            for n in sizes])
#: Deepest nesting accepted (lists in tuples in dicts ...); learners' results are shallow.
MAX_DEPTH = 32
#: Packages whose functions and dataclasses may be named in a message.
PACKAGE = "kalman_course"


class NotPlainData(ValueError):
    """A message holds something that is not plain data, or is malformed."""


@dataclasses.dataclass(frozen=True)
class Opaque:
    """What the learner's code returned when it was not plain data: only its type's name."""

    type_name: str

    def __repr__(self) -> str:
        return f"<a {self.type_name}>"


@dataclasses.dataclass(frozen=True)
class Raised:
    """An exception raised by the learner's code: its type's name and its message."""

    type_name: str
    message: str


@dataclasses.dataclass(frozen=True)
class LearnerName:
    """A name in the learner's notebook (a function the check hands to another one)."""

    name: str


# ---------------------------------------------------------------------------------------
# encoding
# ---------------------------------------------------------------------------------------

def _plain_dtype(dtype: np.dtype) -> bool:
    return dtype.char == "?" or dtype.newbyteorder("<").str in DTYPES


def _array_record(kind: str, value: np.ndarray) -> dict:
    dtype = value.dtype.newbyteorder("<") if value.dtype.byteorder == ">" else value.dtype
    data = np.ascontiguousarray(value, dtype=dtype).tobytes()
    return {"~": kind, "dtype": "?" if dtype.char == "?" else dtype.str, "shape": list(np.shape(value)),
            "data": base64.b64encode(data).decode("ascii")}


def import_path(obj) -> str:
    """``module:qualname`` of a module-level function or class (``NotPlainData`` otherwise)."""
    module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", "")
    if not module or not qualname or "<" in qualname:
        raise NotPlainData(f"{obj!r} has no import path (a lambda or a nested function?)")
    return f"{module}:{qualname}"


def encode(value, *, towards_kernel: bool, convert: Callable | None = None, memo: dict | None = None) -> str:
    """Encode ``value`` as JSON text.

    Parameters
    ----------
    value : object
        Plain data, as listed in the module docstring.
    towards_kernel : bool
        True for a request (functions and learner names may be named), False for a result.
    convert : callable, optional
        Called with anything else; returns a replacement to encode, or raises. The kernel
        uses it to turn a learner's non-plain result into an array or an :class:`Opaque`.
    memo : dict, optional
        ``id(object) -> handle`` of dataclass instances already sent in this session: each
        is sent whole once and then by handle (the excerpts are megabytes).
    """
    def enc(v, depth):
        if depth > MAX_DEPTH:
            raise NotPlainData(f"nested deeper than {MAX_DEPTH} levels")
        if v is None or type(v) in (bool, int, str):
            return v
        if type(v) is float:
            return v if math.isfinite(v) else {"~": "float", "repr": repr(v)}
        if type(v) is list:
            return [enc(x, depth + 1) for x in v]
        if type(v) is tuple:
            return {"~": "tuple", "items": [enc(x, depth + 1) for x in v]}
        if type(v) is dict:
            return {"~": "dict", "items": [[enc(k, depth + 1), enc(x, depth + 1)] for k, x in v.items()]}
        if type(v) is np.ndarray and _plain_dtype(v.dtype):
            return _array_record("array", v)
        if isinstance(v, np.generic) and type(v) is np.dtype(type(v)).type and _plain_dtype(np.dtype(type(v))):
            return _array_record("scalar", np.asarray(v))
        if isinstance(v, Raised):
            return {"~": "raised", "type": str(v.type_name), "message": str(v.message)}
        if isinstance(v, Opaque):
            return {"~": "opaque", "type": str(v.type_name)}
        if towards_kernel and isinstance(v, LearnerName):
            return {"~": "learner", "name": v.name}
        if dataclasses.is_dataclass(v) and not isinstance(v, type) and type(v).__module__.startswith(PACKAGE) \
                and type(v).__module__ != __name__:
            return enc_dataclass(v, depth)
        if towards_kernel:
            if isinstance(v, functools.partial):
                return {"~": "partial", "func": enc(v.func, depth + 1), "args": enc(tuple(v.args), depth + 1),
                        "keywords": enc(dict(v.keywords), depth + 1)}
            if isinstance(v, types.FunctionType) and (v.__module__ or "").startswith(PACKAGE):
                return {"~": "function", "ref": import_path(v)}
        if convert is not None:
            return enc(convert(v), depth + 1)
        raise NotPlainData(f"a {type(v).__name__} is not plain data")

    def enc_dataclass(v, depth):
        key = id(v)
        if memo is not None and key in memo:
            return {"~": "handle", "id": memo[key][0]}
        fields = {f.name: enc(getattr(v, f.name), depth + 1) for f in dataclasses.fields(v) if f.init}
        record = {"~": "dataclass", "type": import_path(type(v)), "fields": fields}
        if memo is not None:
            memo[key] = (len(memo), v)  # keeps v alive, so its id is not reused
            record["id"] = memo[key][0]
        return record

    return json.dumps(enc(value, 0), separators=(",", ":"))


# ---------------------------------------------------------------------------------------
# decoding
# ---------------------------------------------------------------------------------------

def _resolve(path: str, *, want_class: bool):
    """The package function or dataclass named ``module:qualname``."""
    module, _, qualname = str(path).partition(":")
    if not (module == PACKAGE or module.startswith(PACKAGE + ".")) or not qualname:
        raise NotPlainData(f"{path!r} is not in the {PACKAGE} package")
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    if want_class and not (isinstance(obj, type) and dataclasses.is_dataclass(obj)):
        raise NotPlainData(f"{path!r} is not a dataclass")
    if not want_class and not callable(obj):
        raise NotPlainData(f"{path!r} is not a function")
    return obj


def _array(record: dict, scalar: bool):
    dtype = record.get("dtype")
    if dtype not in DTYPES:
        raise NotPlainData(f"dtype {dtype!r} is not plain data")
    shape = record.get("shape")
    if not isinstance(shape, list) or not all(type(n) is int and n >= 0 for n in shape):
        raise NotPlainData("an array's shape must be a list of non-negative ints")
    try:
        raw = base64.b64decode(record.get("data", ""), validate=True)
    except (ValueError, TypeError):
        raise NotPlainData("an array's data is not base64") from None
    dt = np.dtype(dtype)
    if len(raw) != dt.itemsize * math.prod(shape):
        raise NotPlainData("an array's data does not match its shape")
    arr = np.frombuffer(raw, dtype=dt).reshape(shape).astype(dt.newbyteorder("="), copy=True)
    if scalar:
        if shape:
            raise NotPlainData("a numpy scalar must have shape []")
        return arr[()]
    return arr


def decode(text: str, *, from_kernel: bool, learner_lookup: Callable | None = None,
           handles: dict | None = None):
    """Decode JSON text from :func:`encode` into exact builtin and numpy types.

    Parameters
    ----------
    text : str
        The message.
    from_kernel : bool
        True in the grading process (results: no functions, no learner names); False in the
        kernel (requests).
    learner_lookup : callable, optional
        In the kernel: ``name -> object`` for the learner's names.
    handles : dict, optional
        In the kernel: handle -> object of the dataclass instances received whole earlier.

    Raises
    ------
    NotPlainData
        If the text is not JSON, or holds anything the module docstring does not list.
    """
    try:
        tree = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise NotPlainData(f"not JSON ({type(exc).__name__})") from None

    def dec(v, depth):
        if depth > MAX_DEPTH:
            raise NotPlainData(f"nested deeper than {MAX_DEPTH} levels")
        if v is None or type(v) in (bool, int, float, str):
            return v
        if type(v) is list:
            return [dec(x, depth + 1) for x in v]
        if type(v) is not dict:
            raise NotPlainData(f"unexpected JSON value {type(v).__name__}")
        kind = v.get("~")
        if kind == "float":
            if v.get("repr") not in ("nan", "inf", "-inf"):
                raise NotPlainData("a non-finite float must be nan, inf or -inf")
            return float(v["repr"])
        if kind == "tuple":
            return tuple(dec(x, depth + 1) for x in _items(v))
        if kind == "dict":
            out = {}
            for pair in _items(v):
                if type(pair) is not list or len(pair) != 2:
                    raise NotPlainData("a dict's items must be [key, value] pairs")
                key = dec(pair[0], depth + 1)
                try:
                    hash(key)
                except TypeError:
                    raise NotPlainData("a dict key must be hashable") from None
                out[key] = dec(pair[1], depth + 1)
            return out
        if kind in ("array", "scalar"):
            return _array(v, kind == "scalar")
        if kind == "dataclass":
            cls = _resolve(v.get("type"), want_class=True)
            fields = v.get("fields")
            if type(fields) is not dict:
                raise NotPlainData("a dataclass's fields must be an object")
            try:
                obj = cls(**{str(k): dec(x, depth + 1) for k, x in fields.items()})
            except NotPlainData:
                raise
            except Exception as exc:
                raise NotPlainData(f"cannot rebuild a {cls.__name__}: {type(exc).__name__}: {exc}") from None
            if handles is not None and type(v.get("id")) is int:
                handles[v["id"]] = obj
            return obj
        if kind == "opaque" and from_kernel:
            return Opaque(str(v.get("type", "object")))
        if kind == "raised" and from_kernel:
            return Raised(str(v.get("type", "Exception")), str(v.get("message", "")))
        if not from_kernel:
            if kind == "handle" and handles is not None and v.get("id") in handles:
                return handles[v["id"]]
            if kind == "function":
                return _resolve(v.get("ref"), want_class=False)
            if kind == "partial":
                func = dec(v.get("func"), depth + 1)
                return functools.partial(func, *dec(v.get("args"), depth + 1), **dec(v.get("keywords"), depth + 1))
            if kind == "learner" and learner_lookup is not None:
                return learner_lookup(str(v.get("name")))
        raise NotPlainData(f"{kind!r} records are not accepted here")

    return dec(tree, 0)


def _items(record: dict) -> list:
    items = record.get("items")
    if type(items) is not list:
        raise NotPlainData("a container's items must be a list")
    return items
