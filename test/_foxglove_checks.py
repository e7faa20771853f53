"""Checks a Foxglove user relies on, over a bag read with third-party decoders only."""
from __future__ import annotations

from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

WORLD = "world"


def decode_all(bag: Path) -> dict[str, list]:
    """Every message of every topic, decoded by rosbags' AnyReader; each also decoded by mcap_ros2's
    DecoderFactory from the MCAP files' own schemas (the route Foxglove takes). topic -> messages."""
    out: dict[str, list] = {}
    with AnyReader([Path(bag)]) as r:
        for conn, _, raw in r.messages():
            out.setdefault(conn.topic, []).append(r.deserialize(raw, conn.msgtype))
    counts: dict[str, int] = {}
    for mcap_file in sorted(Path(bag).glob("*.mcap")):
        with open(mcap_file, "rb") as f:
            for _, channel, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
                assert msg is not None
    assert counts == {t: len(v) for t, v in out.items()}, (counts, {t: len(v) for t, v in out.items()})
    return out


def tf_parents(messages: dict[str, list]) -> dict[str, str]:
    """child -> parent over every transform in /tf and /tf_static."""
    parents: dict[str, str] = {}
    for topic in ("/tf_static", "/tf"):
        for m in messages.get(topic, []):
            for t in m.transforms:
                parents[t.child_frame_id] = t.header.frame_id
    return parents


def unconnected(frames, parents: dict[str, str]) -> list[str]:
    """Frames from which following parents never reaches `world`."""
    bad = []
    for f in frames:
        seen = set()
        while f != WORLD and f in parents and f not in seen:
            seen.add(f)
            f = parents[f]
        if f != WORLD:
            bad.append(f)
    return bad
