"""Full `ros2msg` schema text for installed message types (what rosbag2 stores per MCAP schema).

The text is the type's .msg definition followed, for each nested type in first-use order, by a
line of 80 '=', a line `MSG: pkg/Type` and that type's definition: the layout rosbag2 writes
and that rosbags, Foxglove and mcap-ros2-support parse. Definitions come from the .msg files
under `<prefix>/share/<pkg>/msg/`; service/action-derived types (`X_Request`, `X_Goal`,
`X_FeedbackMessage`, `X_Event`, ...) come from their .srv/.action sections or, for the
synthesized wrappers, from the rosidl type description JSON next to them. Pure: no rclpy.
"""
from __future__ import annotations

import functools
import json
import os
import re
import sys
from pathlib import Path

from skillgen_ros.core.errors import BagError

SEPARATOR = "=" * 80
PRIMITIVES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string", "wstring", "time", "duration",
})
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
    parts = type_name.strip().split("/")
    if len(parts) == 2:
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
            base = short_name(t["nested_type_name"])
        else:
            base = _FIELD_TYPES[base_id]
            if base_id in (21, 22) and scap:
                base += f"<={scap}"
        lines.append(f"{base}{suffix} {f['name']}")
    return "\n".join(lines) + "\n"


@functools.lru_cache(maxsize=None)
def definition(type_name: str) -> str:
    """The type's own definition text (no nested types); BagError UNKNOWN_TYPE if not installed."""
    pkg, kind, name = split_type(type_name)
    if kind == "msg":
        path = _find(pkg, "msg", name + ".msg")
        if path is not None:
            return path.read_text()
    parts = {"srv": _SRV_PARTS, "action": _ACTION_PARTS}.get(kind, ())
    hit = _derived(name, parts) if parts else None
    if hit is not None:
        path = _find(pkg, kind, f"{hit[0]}.{kind}")
        if path is not None:
            sections = re.split(r"^---\s*$", path.read_text(), flags=re.M)
            if len(sections) == len(parts):
                return sections[hit[1]].strip("\n") + "\n"
    fields = _description_fields(pkg, kind, name)
    if fields is not None:
        return _fields_to_msg(fields)
    raise BagError(f"no definition found for message type '{type_name}' under "
                   f"{[str(d) for d in share_dirs()]}", "UNKNOWN_TYPE")


def nested_types(text: str, pkg: str) -> list[str]:
    """Non-primitive field types referenced by one definition, as pkg/msg/Type (or pkg/kind/T)."""
    out: list[str] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tokens = line.split()
        if len(tokens) < 2 or "=" in tokens[0] or re.match(r"^\w+\s*=", " ".join(tokens[1:])):
            continue  # constants (TYPE NAME=value) reference no types
        base = re.sub(r"\[.*?\]$", "", tokens[0])
        base = base.split("<=", 1)[0]
        if base in PRIMITIVES or base in ("wchar",):
            continue
        if base == "Header":
            full = "std_msgs/msg/Header"
        elif "/" in base:
            p, k, n = split_type(base)
            full = f"{p}/{k}/{n}"
        else:
            full = f"{pkg}/msg/{base}"
        if full not in out:
            out.append(full)
    return out


@functools.lru_cache(maxsize=None)
def schema_text(type_name: str) -> str:
    """Full ros2msg schema: root definition, then every nested type once, depth-first."""
    pkg, kind, name = split_type(type_name)
    root = definition(f"{pkg}/{kind}/{name}")
    order: list[str] = []

    def visit(text: str, owner_pkg: str) -> None:
        for sub in nested_types(text, owner_pkg):
            if sub not in order:
                order.append(sub)
                visit(definition(sub), split_type(sub)[0])

    visit(root, pkg)
    chunks = [root if root.endswith("\n") else root + "\n"]
    for sub in order:
        body = definition(sub)
        chunks.append(f"{SEPARATOR}\nMSG: {short_name(sub)}\n{body if body.endswith(chr(10)) else body + chr(10)}")
    return "".join(chunks)


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
    return ""
