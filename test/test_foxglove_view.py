"""`skillgen view`: a WebSocket client speaking the Foxglove protocol receives the graph's
/joint_states and the synthesized /tf from a running driver; the server binds loopback only."""
from __future__ import annotations

import asyncio
import json
import re
import struct

import psutil
import pytest
import websockets
from rosbags.typesys import Stores, get_typestore

from conftest import wait_for
from skillgen_ros.core.viz.description import resolve_package_uri
from skillgen_ros.core.viz.messages import TF_TYPE, decode

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01
FETCH_ASSET_RESPONSE = 0x04


def _port(view) -> int | None:
    m = re.search(r"Foxglove live view on ws://127\.0\.0\.1:(\d+)", view.output())
    return int(m.group(1)) if m else None


async def _receive(port: int, topics: set[str], budget: int = 4000) -> tuple[dict, dict]:
    """Subscribe to `topics` once advertised; returns (advertised channels by topic, first payload by topic)."""
    channels, got, subs = {}, {}, {}
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, max_size=1 << 26) as ws:
        for _ in range(budget):  # frames, not seconds: a bound on work, never a sleep
            frame = await asyncio.wait_for(ws.recv(), 60)
            if isinstance(frame, str):
                msg = json.loads(frame)
                if msg.get("op") == "advertise":
                    new = [c for c in msg["channels"] if c["topic"] in topics and c["topic"] not in channels]
                    for c in new:
                        channels[c["topic"]] = c
                        subs[len(subs) + 1] = c["topic"]
                    if new:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                            {"id": sid, "channelId": channels[t]["id"]} for sid, t in subs.items()
                            if t in {c["topic"] for c in new}]}))
            elif frame[0] == MESSAGE_DATA:
                sid, _log_ns = struct.unpack_from("<IQ", frame, 1)
                got.setdefault(subs[sid], bytes(frame[13:]))
                if set(got) == topics:
                    break
    return channels, got


def test_view_serves_joint_states_and_tf(start_node):
    driver = start_node("mock_driver")
    view = start_node("skillgen", "view", "--port", "0")
    assert wait_for(lambda: _port(view) is not None, 60), view.output()
    assert wait_for(lambda: "serving /joint_states" in view.output(), 60), view.output()
    channels, got = asyncio.run(_receive(_port(view), {"/joint_states", "/tf", "/robot_description"}))
    assert channels["/tf"]["schemaName"] == TF_TYPE and channels["/tf"]["encoding"] == "cdr"
    assert channels["/joint_states"]["schemaEncoding"] == "ros2msg"
    js = get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(got["/joint_states"], "sensor_msgs/msg/JointState")
    assert "panda_joint1" in list(js.name)
    tf = decode(got["/tf"], TF_TYPE)
    assert {t.child_frame_id for t in tf.transforms} >= {"panda_link1", "panda_link7"}
    assert "package://franka_panda/meshes/" in decode(got["/robot_description"], "std_msgs/msg/String").data
    assert driver.proc.poll() is None and view.proc.poll() is None
    listening = {c.laddr for c in psutil.Process(view.proc.pid).net_connections(kind="inet")
                 if c.status == psutil.CONN_LISTEN}
    assert listening == {("127.0.0.1", _port(view))}, listening  # loopback only (exec kept the pid)


def test_view_binds_another_address_only_when_asked_and_says_so(start_node):
    view = start_node("skillgen", "view", "--port", "0", "--host", "0.0.0.0", "--no-scene")
    assert wait_for(lambda: "NOT loopback" in view.output(), 60), view.output()
    port = int(re.search(r"ws://0\.0\.0\.0:(\d+)", view.output()).group(1))
    listening = {c.laddr for c in psutil.Process(view.proc.pid).net_connections(kind="inet")
                 if c.status == psutil.CONN_LISTEN}
    assert ("0.0.0.0", port) in listening, listening


async def _fetch(port: int, uris: list[str], budget: int = 4000) -> dict[str, tuple[int, bytes]]:
    """fetchAsset each URI; uri -> (status, data) from the binary replies (opcode 0x04)."""
    out = {}
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, max_size=1 << 26) as ws:
        for k, uri in enumerate(uris):
            await ws.send(json.dumps({"op": "fetchAsset", "uri": uri, "requestId": k}))
        for _ in range(budget):
            frame = await asyncio.wait_for(ws.recv(), 60)
            if isinstance(frame, bytes) and frame[0] == FETCH_ASSET_RESPONSE:
                rid, status, n = struct.unpack_from("<IBI", frame, 1)
                out[uris[rid]] = (status, bytes(frame[10 + n:]) if status == 0 else frame[10:10 + n])
                if len(out) == len(uris):
                    break
    return out


def test_view_serves_the_robot_meshes_and_nothing_else(start_node):
    view = start_node("skillgen", "view", "--port", "0", "--no-scene")
    assert wait_for(lambda: _port(view) is not None, 60), view.output()
    mesh = "package://franka_panda/meshes/visual/link1.obj"
    got = asyncio.run(_fetch(_port(view), [mesh, "package://franka_panda/../../../../etc/passwd", "file:///etc/passwd"]))
    assert got[mesh][0] == 0 and got[mesh][1] == resolve_package_uri(mesh).read_bytes()
    assert got["file:///etc/passwd"][0] != 0 and got["package://franka_panda/../../../../etc/passwd"][0] != 0


def test_view_rejects_a_bad_port_with_a_reason(start_node):
    view = start_node("skillgen", "view", "--port", "70000")
    assert view.proc.wait(60) == 2
    assert "INVALID_PARAMETER" in view.output() and "Traceback" not in view.output()
