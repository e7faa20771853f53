"""Full `ros2msg` schema text for installed message types (what rosbag2 stores per MCAP schema).

The installed definitions are parsed with rosbags.typesys (`get_types_from_msg` for .msg files
and .srv/.action sections, `get_types_from_idl` for packages that ship only .idl) into one
typestore per root type, with every nested type loaded from its own package; the schema text is
then `Typestore.generate_msgdef(type, ros_version=2)`: the root definition, then per nested type
a line of 80 '=', `MSG: pkg/Type` and its definition, the layout rosbag2 writes and rosbags,
Foxglove and mcap-ros2-support parse. Synthesized service/action wrappers (`X_SendGoal_Request`,
`X_FeedbackMessage`, `X_Event`, ...) have no .msg text: their fields come from the rosidl type
description JSON installed next to the .action/.srv. A standard type with no installed
definition (tf2_msgs/msg/TFMessage: not on PyPI) takes rosbags' own ROS 2 Jazzy definition
(`standard_schema_text`), so the recorder can write /tf under its standard name. Pure: no rclpy.
"""
from __future__ import annotations

import functools
import json
import os
import re
import sys
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.base import Nodetype

from skillgen_ros.core.errors import BagError

SEPARATOR = "=" * 80
# rosidl type_description_interfaces/FieldType ids -> .msg primitive names.
_FIELD_TYPES = {
    2: "int8", 3: "uint8", 4: "int16", 5: "uint16", 6: "int32", 7: "uint32", 8: "int64",
    9: "uint64", 10: "float32", 11: "float64", 12: "float64", 13: "char", 14: "wchar",
    15: "bool", 16: "byte", 17: "string", 18: "wstring", 19: "string", 20: "wstring",
    21: "string", 22: "wstring",
}
_SRV_PARTS = ("Request", "Response")
_ACTION_PARTS = ("Goal", "Result", "Feedback")


def split_type(type_name: str) -> tuple[str, str, str]:
    """'pkg/msg/Type' or 'pkg/Type' -> (pkg, kind, Type); kind is msg, srv or action."""
    parts = type_name.strip().split("/") if isinstance(type_name, str) else []
    if len(parts) == 2 and all(parts):
        return parts[0], "msg", parts[1]
    if len(parts) == 3 and parts[1] in ("msg", "srv", "action") and all(parts):
        return parts[0], parts[1], parts[2]
    raise BagError(f"'{type_name}' is not a ROS type name like pkg/msg/Type", "BAD_TYPE_NAME")


def short_name(type_name: str) -> str:
    """Name used inside schema text: pkg/Type for messages, pkg/kind/Type otherwise."""
    pkg, kind, name = split_type(type_name)
    return f"{pkg}/{name}" if kind == "msg" else f"{pkg}/{kind}/{name}"


def share_dirs() -> tuple[Path, ...]:
    """Install prefixes' share/ dirs: AMENT_PREFIX_PATH entries, then this interpreter's prefix."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    seen: list[Path] = []
    for p in prefixes:
        d = Path(p) / "share"
        if d.is_dir() and d not in seen:
            seen.append(d)
    return tuple(seen)


def _find(pkg: str, kind: str, filename: str) -> Path | None:
    for share in share_dirs():
        path = share / pkg / kind / filename
        if path.is_file():
            return path
    return None


def _derived(name: str, parts: tuple[str, ...]) -> tuple[str, int] | None:
    for i, part in enumerate(parts):
        if name.endswith("_" + part):
            return name[: -len(part) - 1], i
    return None


def _description_fields(pkg: str, kind: str, name: str) -> list[dict] | None:
    """Fields of `pkg/kind/name` from a type description JSON in that package (rosidl output)."""
    base = name.split("_")[0]
    for stem in dict.fromkeys((name, base)):
        path = _find(pkg, kind, stem + ".json")
        if path is None:
            continue
        doc = json.loads(path.read_text())["type_description_msg"]
        full = f"{pkg}/{kind}/{name}"
        for desc in [doc["type_description"], *doc["referenced_type_descriptions"]]:
            if desc["type_name"] == full:
                return desc["fields"]
    return None


def _fields_to_msg(fields: list[dict]) -> str:
    """rosidl description fields -> .msg text (input for get_types_from_msg, never output)."""
    lines = []
    for f in fields:
        t = f["type"]
        tid, cap, scap = t["type_id"], t["capacity"], t["string_capacity"]
        base_id, suffix = tid, ""
        if tid > 144:
            base_id, suffix = tid - 144, "[]"
        elif tid > 96:
            base_id, suffix = tid - 96, f"[<={cap}]"
        elif tid > 48:
            base_id, suffix = tid - 48, f"[{cap}]"
        if base_id == 1:
            base = t["nested_type_name"]
        else:
            base = _FIELD_TYPES[base_id]
            if base_id in (21, 22) and scap:
                base += f"<={scap}"
        lines.append(f"{base}{suffix} {f['name']}")
    return "\n".join(lines) + "\n"


def _msg_text(pkg: str, kind: str, name: str) -> str | None:
    """The installed .msg text, or the matching section of the .srv/.action file."""
    if kind == "msg":
        path = _find(pkg, "msg", name + ".msg")
        return path.read_text() if path is not None else None
    hit = _derived(name, {"srv": _SRV_PARTS, "action": _ACTION_PARTS}[kind])
    path = _find(pkg, kind, f"{hit[0]}.{kind}") if hit else None
    if path is None:
        return None
    sections = re.split(r"^---\s*$", path.read_text(), flags=re.M)
    return sections[hit[1]] if len(sections) == len({"srv": _SRV_PARTS}.get(kind, _ACTION_PARTS)) else None


def _ours(name: str) -> str:
    """rosbags files srv/action types as pkg/srv/msg/X; ours is pkg/srv/X."""
    parts = name.split("/")
    return "/".join(parts[:2] + parts[3:]) if len(parts) == 4 and parts[2] == "msg" else name


def _theirs(name: str) -> str:
    pkg, kind, n = split_type(_ours(name))
    return f"{pkg}/msg/{n}" if kind == "msg" else f"{pkg}/{kind}/msg/{n}"


def _fix_ref(desc, pkg: str):
    """Field type names in rosbags' form; a .srv/.action section's relative name is pkg/msg/X."""
    kind, spec = desc
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return kind, (_fix_ref(spec[0], pkg), spec[1])
    if kind == Nodetype.NAME:
        p, k, n = split_type(_ours(spec))
        if p == pkg and k in ("srv", "action") and not any(
                _derived(n, parts) for parts in (_SRV_PARTS, _ACTION_PARTS)) and _find(p, "msg", n + ".msg"):
            k = "msg"
        return kind, _theirs(f"{p}/{k}/{n}")
    return desc


def _rosbags_types(types: dict, pkg: str) -> dict:
    return {_theirs(t): (consts, [(f, _fix_ref(d, pkg)) for f, d in fields])
            for t, (consts, fields) in types.items()}


def _load(type_name: str) -> dict:
    """rosbags typesdict for one installed type (msg text, else idl, else type description JSON)."""
    pkg, kind, name = split_type(type_name)
    full = f"{pkg}/{kind}/{name}"
    text = _msg_text(pkg, kind, name)
    if text is not None:
        return _rosbags_types(get_types_from_msg(text, full), pkg)
    idl = _find(pkg, kind, name + ".idl")
    if idl is not None:
        types = {_ours(t): v for t, v in get_types_from_idl(idl.read_text()).items()}
        if full in types:
            return _rosbags_types({full: types[full]}, pkg)
    fields = _description_fields(pkg, kind, name)
    if fields is not None:
        return _rosbags_types(get_types_from_msg(_fields_to_msg(fields), full), pkg)
    raise BagError(f"no definition found for message type '{type_name}' under "
                   f"{[str(d) for d in share_dirs()]}", "UNKNOWN_TYPE")


def _refs(desc) -> list[str]:
    kind, spec = desc
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return _refs(spec[0])
    return [_ours(spec)] if kind == Nodetype.NAME else []


@functools.lru_cache(maxsize=None)
def typestore(type_name: str):
    """A rosbags Typestore holding `type_name` and every type it nests, from installed files."""
    pkg, kind, name = split_type(type_name)
    store = get_typestore(Stores.EMPTY)
    pending, seen = [f"{pkg}/{kind}/{name}"], set()
    while pending:
        t = pending.pop()
        if t in seen:
            continue
        seen.add(t)
        types = _load(t)
        store.register(types)
        for _, fields in types.values():
            pending += [r for _, d in fields for r in _refs(d) if r not in seen]
    return store


@functools.lru_cache(maxsize=None)
def schema_text(type_name: str) -> str:
    """Full ros2msg schema (rosbags' generate_msgdef over the installed definitions)."""
    pkg, kind, name = split_type(type_name)
    full = f"{pkg}/{kind}/{name}"
    try:
        text, _ = typestore(full).generate_msgdef(_theirs(full), ros_version=2)
    except BagError as e:
        if e.reason == "UNKNOWN_TYPE" and kind == "msg":
            standard = standard_schema_text(full)
            if standard:
                return standard
        raise
    except Exception as e:  # rosbags raises TypesysError and friends on a bad definition
        raise BagError(f"cannot build the schema of '{type_name}': {type(e).__name__}: {e}",
                       "BAD_SCHEMA") from None
    return text


@functools.lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """RIHS01 type description hash from rosidl's JSON, or '' when the JSON is not installed."""
    pkg, kind, name = split_type(type_name)
    full = f"{pkg}/{kind}/{name}"
    base = name.split("_")[0]
    for stem in dict.fromkeys((name, base)):
        path = _find(pkg, kind, stem + ".json")
        if path is None:
            continue
        for entry in json.loads(path.read_text()).get("type_hashes", []):
            if entry.get("type_name") == full:
                return entry.get("hash_string", "")
    if kind == "msg" and _find(pkg, "msg", name + ".msg") is None and standard_schema_text(full):
        from rosbags.typesys import Stores  # a standard type we write by rosbags' definition (tf2_msgs)

        return get_typestore(Stores.ROS2_JAZZY).hash_rihs01(full)  # agrees with rosidl's (JointState checked)
    return ""


def standard_schema_text(type_name: str) -> str:
    """rosbags' ROS 2 Jazzy schema of a standard message type, or '' if rosbags does not know it."""
    from rosbags.typesys import Stores

    store = get_typestore(Stores.ROS2_JAZZY)
    pkg, kind, name = split_type(type_name)
    full = f"{pkg}/msg/{name}"
    if kind != "msg" or full not in store.types:
        return ""
    return store.generate_msgdef(full, ros_version=2)[0]
