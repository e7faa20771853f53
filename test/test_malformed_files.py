"""Malformed files (issue 19): bags (truncated, bit-flipped chunk, wrong CRC, absurd length fields,
missing schema), HDF5 datasets (truncated, missing keys, wrong shapes), graph/params YAML and
annotation files. Each gives a SkillGenError whose message names the file and the problem, and
reading it never allocates (Python heap, tracemalloc) more than twice the file's size plus a
fixed 16 MiB. (Node params files with bad YAML: test_cli_launch.py's invalid-params test.)
`CASES` is counted by bench/reliability/run.py.
"""
from __future__ import annotations

import shutil
import struct
import tracemalloc
from pathlib import Path
from typing import Callable

import h5py
import numpy as np
import pytest
from mcap.writer import Writer
from rclpy.serialization import serialize_message
from skillgen_interfaces.msg import OscTarget

from skillgen_ros.core.bag import schemas
from skillgen_ros.core.bag.reader import BagReader
from skillgen_ros.core.bag.writer import BagWriter, Compression, TopicSpec, WriterOptions
from skillgen_ros.core.errors import SkillGenError

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "bags" / "Square" / "demo_00"
SLACK = 16 << 20


def _bag(tmp: Path, name: str = "bag", compression: str = "zstd") -> tuple[Path, Path]:
    p = tmp / name
    with BagWriter(p, WriterOptions(compression=Compression(compression), chunk_size=2000)) as w:
        w.add_topic(TopicSpec("/osc_target", "skillgen_interfaces/msg/OscTarget"))
        for i in range(300):
            w.write("/osc_target", serialize_message(OscTarget(gripper=float(i))), 10**9 + i * 10**7)
    return p, next(p.glob("*.mcap"))


def _first_chunk(data: bytes) -> tuple[int, int]:
    i = 8
    while i < len(data):
        op, ln = data[i], struct.unpack_from("<Q", data, i + 1)[0]
        if op == 0x06:
            return i, ln
        i += 9 + ln
    raise AssertionError("no chunk")


def _mutated(tmp: Path, mutate: Callable[[bytearray], None], compression: str = "zstd") -> tuple[Path, Path]:
    p, f = _bag(tmp, compression=compression)
    data = bytearray(f.read_bytes())
    mutate(data)
    f.write_bytes(bytes(data))
    return p, f


def _read_all(path: Path) -> None:
    r = BagReader(path)
    for m in r.messages():
        r.decode(m)


def _flip_chunk_byte(d: bytearray) -> None:
    i, ln = _first_chunk(d)
    d[i + 9 + ln // 2] ^= 0xFF


def _wrong_crc(d: bytearray) -> None:
    i, _ = _first_chunk(d)
    struct.pack_into("<I", d, i + 9 + 24, 12345)  # chunk: start, end, uncompressed size, crc


def _absurd_summary_offset(d: bytearray) -> None:
    struct.pack_into("<Q", d, len(d) - 8 - 20, 2**62)  # footer: summary_start -> past the end


def _bag_case(mutate, problem: str, compression: str = "zstd"):
    def run(tmp: Path):
        p, f = _mutated(tmp, mutate, compression)
        return f, lambda: _read_all(p), problem
    return run


def _truncated_source_demo(tmp: Path):
    from skillgen_ros.core.skills.bag_demos import load_source_demo
    from skillgen_ros.core.tasks import get_task

    copy = tmp / "demo_00"
    shutil.copytree(SHIPPED, copy)
    f = next(copy.glob("*.mcap"))
    f.write_bytes(f.read_bytes()[: f.stat().st_size * 2 // 3])
    return f, lambda: load_source_demo(copy, get_task("Square")), "truncated"


def _missing_schema(tmp: Path):
    from skillgen_ros.core.skills.bag_demos import load_source_demo
    from skillgen_ros.core.tasks import get_task

    copy = tmp / "demo_00"
    copy.mkdir()
    shutil.copy(SHIPPED / "annotations.yaml", copy)
    src = BagReader(SHIPPED)
    with open(copy / "demo_00_0.mcap", "wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="test")
        ids = {}
        for t in src.topics.values():  # every channel, /joint_states without its schema
            sid = 0 if t.name == "/joint_states" else w.register_schema(t.type, "ros2msg", t.schema_text.encode())
            ids[t.name] = w.register_channel(t.name, "cdr", sid, {})
        for m in src.messages():
            w.add_message(ids[m.topic], log_time=m.log_time_ns, publish_time=m.publish_time_ns, data=m.data)
        for name, rec in src.metadata_records.items():
            w.add_metadata(name, rec)
        w.finish()
    return copy / "demo_00_0.mcap", lambda: load_source_demo(copy, get_task("Square")), "schema"


def _not_mcap(tmp: Path):
    f = tmp / "x.mcap"
    f.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(200))
    return f, lambda: _read_all(f), "not an MCAP"


def _dataset(tmp: Path) -> Path:
    """A small valid generated dataset (the suite's fake generator)."""
    from test_dataset_hdf5 import demos as _demos_fixture  # noqa: F401  (fixture function, not called)
    from test_dataset_hdf5 import generate
    from _generation_fakes import make_source_demos

    return Path(generate(tmp / "ds", make_source_demos(2), n=1).dataset_path)


def _hdf5_case(mutate, problem: str, loader: str = "validate"):
    def run(tmp: Path):
        from skillgen_ros.core.dataset.hdf5 import validate_dataset
        from skillgen_ros.core.learning.data import dataset_info

        p = _dataset(tmp)
        mutate(p)
        load = {"validate": lambda: validate_dataset(str(p)), "info": lambda: dataset_info(str(p))}[loader]
        return p, load, problem
    return run


def _truncate(p: Path) -> None:
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])


def _h5(edit):
    def mutate(p: Path):
        with h5py.File(p, "a") as f:
            edit(f)
    return mutate


def _reshape_actions(f) -> None:
    a = f["data/demo_0/actions"][()]
    del f["data/demo_0/actions"]
    f["data/demo_0"].create_dataset("actions", data=a[:, :6])


def _graphs_yaml(tmp: Path):
    from skillgen_ros.graphs import load_graphs

    f = tmp / "graphs.yaml"
    f.write_text("graphs:\n  g: [unclosed\n")
    return f, lambda: load_graphs(f), "cannot read graphs file"


def _annotation(text: str, problem: str):
    def run(tmp: Path):
        from skillgen_ros.core.skills.annotation import load_annotation

        f = tmp / "annotations.yaml"
        f.write_text(text)
        return f, lambda: load_annotation(str(f)), problem
    return run


CASES: dict[str, Callable] = {
    "bag: truncated source demo": _truncated_source_demo,
    "bag: bit-flipped chunk (zstd)": _bag_case(_flip_chunk_byte, "crc"),
    "bag: bit-flipped chunk (uncompressed)": _bag_case(_flip_chunk_byte, "crc", "none"),
    "bag: wrong chunk CRC": _bag_case(_wrong_crc, "crc"),
    "bag: absurd summary offset": _bag_case(_absurd_summary_offset, None),
    "bag: missing schema": _missing_schema,
    "bag: not an MCAP file": _not_mcap,
    "hdf5: truncated": _hdf5_case(_truncate, "not a readable HDF5"),
    "hdf5: truncated (training loader)": _hdf5_case(_truncate, "cannot read dataset", "info"),
    "hdf5: missing key": _hdf5_case(_h5(lambda f: f["data/demo_0"].__delitem__("obs")), "lacks group obs"),
    "hdf5: missing key (training loader)": _hdf5_case(_h5(lambda f: f["data"].attrs.__delitem__("env_args")),
                                                      "env_args", "info"),
    "hdf5: wrong shape": _hdf5_case(_h5(_reshape_actions), "not shaped"),
    "yaml: graphs file": _graphs_yaml,
    "annotation: not YAML": _annotation("skills: [unclosed\n", "not valid YAML"),
    "annotation: wrong structure": _annotation("- just\n- a list\n", ""),
    "annotation: NaN boundary": _annotation("task: Square\nskills:\n  - {name: grasp, start: .nan, end: 3}\n", ""),
}


@pytest.mark.parametrize("case", list(CASES))
def test_malformed_file_gives_a_clear_error_in_bounded_memory(case, tmp_path):
    path, load, problem = CASES[case](tmp_path)
    size = Path(path).stat().st_size
    tracemalloc.start()
    try:
        with pytest.raises(SkillGenError) as e:
            load()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    msg = str(e.value)
    assert e.value.reason and e.value.reason != "ERROR", msg
    assert path.name in msg or str(path.parent.name) in msg, f"the error does not name the file: {msg}"
    if problem is not None:
        assert problem.lower() in msg.lower(), f"the error does not say {problem!r}: {msg}"
    assert peak <= 2 * size + SLACK, (peak, size)


def test_a_truncated_bag_is_read_up_to_its_last_chunk_with_a_warning_naming_it(tmp_path):
    p, f = _mutated(tmp_path, lambda d: d.__delitem__(slice(len(d) * 6 // 10, None)))
    r = BagReader(p)
    assert r.truncated and 0 < r.message_count < 300
    assert any(f.name in w and "BAG_TRUNCATED" in w for w in r.warnings)
    got = [r.decode(m).gripper for m in r.messages()]
    assert got == [float(i) for i in range(len(got))]  # every recovered message intact and in order
