"""Boundary checks every node runs on a request or parameter before work starts (issue 19).

Each check raises a SkillGenError whose `reason` the node puts into its response: non-finite
numbers (NaN, inf), numbers out of range, empty or unknown names, oversized arrays, and output
paths outside the directories the node may write. One place, so every interface rejects the same
input with the same code. Pure: no rclpy.
"""
from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from skillgen_ros.core.errors import InvalidInputError

# A float field where "the default" must be expressible: any negative value selects the default
# (documented in the interface files: Generate.action, RunAttempt.srv). 0 keeps its meaning.
USE_DEFAULT = -1.0
MAX_NAME = 256               # characters in a task/variant/object/topic name
MAX_PATH = 4096              # characters in a path
MAX_ITEMS = 4096             # entries in a list of names or scene objects
MAX_NUMBERS = 1 << 20        # float64 entries in one array field (8 MiB)
MAX_REACH = 10.0             # m from the robot base: a pose farther away is a mistake, not a scene


def finite(name: str, value, lo: float | None = None, hi: float | None = None,
           reason: str = "INVALID_PARAMETER", lo_open: bool = False) -> float:
    """`value` as a float in [lo, hi] (or (lo, hi] with lo_open); NaN and inf are refused."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a number, got {value!r}", reason=reason) from None
    if not math.isfinite(v):
        raise InvalidInputError(f"{name} must be finite, got {v}", reason=reason)
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise InvalidInputError(f"{name} must be {'>' if lo_open else '>='} {lo}, got {v}", reason=reason)
    if hi is not None and v > hi:
        raise InvalidInputError(f"{name} must be <= {hi}, got {v}", reason=reason)
    return v


def or_default(name: str, value, default: float, hi: float, reason: str = "INVALID_PARAMETER") -> float:
    """A float field with the USE_DEFAULT sentinel: negative -> `default`; else finite in [0, hi]."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a number, got {value!r}", reason=reason) from None
    if math.isfinite(v) and v < 0:
        return float(default)
    return finite(name, v, 0.0, hi, reason)


def finite_array(name: str, values, length: int | None = None, max_len: int = MAX_NUMBERS,
                 reason: str = "INVALID_PARAMETER") -> np.ndarray:
    """A 1-D float array: at most max_len entries (exactly `length` if given), all finite."""
    n = len(values)
    if n > max_len:
        raise InvalidInputError(f"{name} has {n} values; at most {max_len} are accepted", reason=reason)
    if length is not None and n != length:
        raise InvalidInputError(f"{name} must have {length} values, got {n}", reason=reason)
    a = np.asarray(values, dtype=float).reshape(-1)
    if not np.all(np.isfinite(a)):
        raise InvalidInputError(f"{name} has non-finite values (NaN or inf)", reason=reason)
    return a


def name(label: str, value, known: Iterable[str] | None = None, allow_empty: bool = False,
         reason: str = "INVALID_NAME") -> str:
    """A non-empty printable name of at most MAX_NAME characters, one of `known` if given."""
    v = str(value)
    if not v:
        if allow_empty:
            return v
        raise InvalidInputError(f"{label} is empty", reason=reason)
    if len(v) > MAX_NAME or not v.isprintable():
        raise InvalidInputError(f"{label} must be at most {MAX_NAME} printable characters, got {v[:40]!r}...",
                                reason=reason)
    if known is not None:
        known = list(known)
        if v not in known:
            raise InvalidInputError(f"unknown {label} {v!r}; known: {', '.join(map(str, known))}", reason=reason)
    return v


def names(label: str, values: Sequence, max_items: int = MAX_ITEMS, **kw) -> list[str]:
    if len(values) > max_items:
        raise InvalidInputError(f"{label} has {len(values)} entries; at most {max_items} are accepted",
                                reason=kw.get("reason", "INVALID_NAME"))
    return [name(label, v, **kw) for v in values]


def default_writable_roots() -> tuple[Path, ...]:
    """Where a node may write when not told otherwise: its working directory and the temp dir."""
    return (Path.cwd().resolve(), Path(tempfile.gettempdir()).resolve())


def writable_path(label: str, path: str, roots: Iterable[str | os.PathLike] = (),
                  reason: str = "OUTPUT_OUTSIDE_ROOTS") -> Path:
    """`path` resolved (symlinks and '..' followed); it must lie under one of `roots` or the
    default roots. Relative paths resolve against the working directory."""
    p = str(path)
    if not p or len(p) > MAX_PATH or "\x00" in p:
        raise InvalidInputError(f"{label} must be a non-empty path of at most {MAX_PATH} characters",
                                reason="INVALID_PATH")
    resolved = Path(p).expanduser().resolve()
    allowed = list(default_writable_roots()) + [Path(r).expanduser().resolve() for r in roots if str(r)]
    if not any(resolved == r or r in resolved.parents for r in allowed):
        raise InvalidInputError(f"{label} {p!r} resolves to {resolved}, outside the directories this node may "
                                f"write ({', '.join(map(str, allowed))}; parameter writable_roots adds more)",
                                reason=reason)
    return resolved
