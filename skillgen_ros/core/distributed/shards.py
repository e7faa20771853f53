"""A distributed run's shards on the driver: shard files, the journal of finished indices, the merge.

Workers send each finished range to the driver as bytes (Ray's object store: no shared filesystem).
The driver writes them under <output_dir>/shards/ (temp name, then rename), then appends one
journal line naming the range's finished indices and their outcomes (fsync'd). An index is done
exactly when its journal line exists, so a run stopped at any moment resumes (`--resume`) by
skipping the journaled indices; a shard file without a journal line is ignored. The final
demo.hdf5 / failed.hdf5 are merged from the shards in index order (core/dataset/hdf5.merge_datasets),
written to a temp name and renamed: they are derived files, rebuilt by a resumed run.
"""
from __future__ import annotations

import dataclasses
import io
import json
import os
import secrets
import tarfile
from dataclasses import dataclass, field
from pathlib import Path

import h5py

from ..errors import InvalidInputError
from ..generation.attempt import AttemptResult
from ..generation.outcome import FailureReason
from ..generation.session import RunRequest, check_output_dir
from ..dataset.hdf5 import merge_datasets
from ..dataset.sink import DATASET_FILE, FAILED_FILE
from .schedule import IndexRange

SHARD_DIR = "shards"
JOURNAL = "journal.jsonl"
REQUEST = "request.json"
# RunRequest fields a resumed run may change: where it writes, how many attempts / successes it wants
_RESUMABLE = ("output_dir", "attempts", "target_successes", "video_attempts", "source_demos")


@dataclass
class ShardPayload:
    """One finished (or stopped) range, as a worker returns it."""

    range: IndexRange
    records: list[AttemptResult]  # episode=None: the arrays are in the files
    demo_bytes: bytes
    failed_bytes: bytes
    worker: str = ""
    seconds: float = 0.0  # the worker's wall time for the range (Ray's overhead = driver time - this)
    attempt_seconds: float = 0.0  # sum of the attempts' own time

    @property
    def indices(self) -> dict[int, bool]:
        return {r.index: r.success for r in self.records}


def _attr(v):
    return v.decode() if isinstance(v, bytes) else v


def _ints(v) -> tuple[int, ...]:
    v = _attr(v)
    return tuple(int(x) for x in (json.loads(v) if isinstance(v, str) else v))


def read_records(*paths: str) -> list[AttemptResult]:
    """Every attempt stored in these files, as AttemptResults without their episode, by index."""
    out = []
    for p in paths:
        if not os.path.exists(p):
            continue
        with h5py.File(p, "r", locking=False) as f:
            for name in f["data"]:
                a = f["data"][name].attrs
                timings = _attr(a.get("timings", "{}"))
                out.append(AttemptResult(
                    index=int(a["index"]), method=_attr(a["method"]), success=bool(a["success"]),
                    reason=FailureReason(_attr(a["reason"])), message=_attr(a.get("message", "")),
                    scene_seed=int(a.get("scene_seed", 0)),
                    source_demos=_ints(a["source_demos"]),
                    episode=None, timings=json.loads(timings) if isinstance(timings, str) else dict(timings)))
    return sorted(out, key=lambda r: r.index)


def pack_shard(out_dir: str, r: IndexRange, worker: str = "", seconds: float = 0.0) -> ShardPayload:
    """A worker's finished range directory as a payload (records read back from the files)."""
    demo, failed = os.path.join(out_dir, DATASET_FILE), os.path.join(out_dir, FAILED_FILE)
    recs = read_records(demo, failed)
    read = lambda p: Path(p).read_bytes() if os.path.exists(p) else b""  # noqa: E731
    return ShardPayload(r, recs, read(demo), read(failed), worker, seconds,
                        sum(x.timings.get("total", 0.0) for x in recs))


def record_json(r: AttemptResult) -> dict:
    return {"index": r.index, "method": r.method, "success": r.success, "reason": r.reason.value,
            "message": r.message, "scene_seed": r.scene_seed, "source_demos": list(r.source_demos),
            "timings": r.timings}


def record_from_json(d: dict) -> AttemptResult:
    return AttemptResult(index=d["index"], method=d["method"], success=d["success"],
                         reason=FailureReason(d["reason"]), message=d["message"], scene_seed=d["scene_seed"],
                         source_demos=tuple(d["source_demos"]), episode=None, timings=d["timings"])


def request_identity(req: RunRequest) -> dict:
    """What must match for a run to resume another: every field that changes an attempt's arrays."""
    d = json.loads(json.dumps(dataclasses.asdict(req), default=str))
    return {k: v for k, v in d.items() if k not in _RESUMABLE}


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


@dataclass
class ShardStore:
    out_dir: str
    records: dict[int, AttemptResult] = field(default_factory=dict)  # index -> journaled outcome
    files: list[tuple[str, str]] = field(default_factory=list)  # (demo, failed) shard files

    @property
    def dir(self) -> Path:
        return Path(self.out_dir) / SHARD_DIR

    def open(self, req: RunRequest, resume: bool) -> "ShardStore":
        """A new run (refuses an output dir with data or shards) or a resumed one (same request)."""
        ident = request_identity(req)
        if not resume:
            check_output_dir(self.out_dir)
            if (self.dir / JOURNAL).exists():
                raise InvalidInputError(f"{self.dir} holds an interrupted run; continue it with --resume "
                                        "or choose a new output", reason="OUTPUT_EXISTS")
            self.dir.mkdir(parents=True, exist_ok=True)
            _write_atomic(self.dir / REQUEST, json.dumps(ident, indent=1, sort_keys=True).encode())
            return self
        if not (self.dir / REQUEST).exists():
            raise InvalidInputError(f"nothing to resume: {self.dir / REQUEST} does not exist",
                                    reason="NOTHING_TO_RESUME")
        old = json.loads((self.dir / REQUEST).read_text())
        diff = sorted(k for k in set(old) | set(ident) if old.get(k) != ident.get(k))
        if diff:
            raise InvalidInputError(f"--resume with a different request than {self.out_dir}'s: {', '.join(diff)} "
                                    "differ", reason="RESUME_MISMATCH")
        self._load_journal()
        return self

    def _load_journal(self) -> None:
        p = self.dir / JOURNAL
        if not p.exists():
            return
        for line in p.read_text().splitlines():
            try:
                e = json.loads(line)
            except ValueError:  # a line cut by a crash: its indices were never done
                continue
            for d in e["records"]:
                self.records[d["index"]] = record_from_json(d)
            if e["files"]:
                self.files.append(tuple(str(self.dir / f) for f in e["files"]))

    @property
    def done(self) -> dict[int, bool]:
        return {i: r.success for i, r in self.records.items()}

    def add(self, p: ShardPayload) -> None:
        """Persist a payload's files, then its journal line (the commit point); nothing for an empty one."""
        if not p.records:
            return
        files = []
        if p.records:
            stem = f"{p.range.first:09d}-{p.range.end:09d}-{secrets.token_hex(3)}"
            files = [f"{stem}.demo.hdf5", f"{stem}.failed.hdf5"]
            _write_atomic(self.dir / files[0], p.demo_bytes)
            _write_atomic(self.dir / files[1], p.failed_bytes)
            self.files.append(tuple(str(self.dir / f) for f in files))
        line = json.dumps({"range": [p.range.first, p.range.end], "worker": p.worker, "files": files,
                           "records": [record_json(r) for r in p.records]})
        with open(self.dir / JOURNAL, "a") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())
        for r in p.records:
            self.records[r.index] = r

    def merge(self, kept: list[int]) -> tuple[str, str]:
        """demo.hdf5 and failed.hdf5 from the shards, only `kept` indices, in index order."""
        keep = set(kept)
        out = []
        for k, name in enumerate((DATASET_FILE, FAILED_FILE)):
            final = Path(self.out_dir) / name
            tmp = final.with_name(name + ".part")
            if tmp.exists():
                tmp.unlink()
            merge_datasets([f[k] for f in self.files], str(tmp), keep=lambda i: i in keep, unique=True)
            os.replace(tmp, final)
            out.append(str(final))
        return out[0], out[1]


_ORIGIN = "skillgen.origin"  # pax header: the packed directory's absolute path on the driver


def pack_dir(path: str) -> bytes:
    """A directory (the source demo bags) as tar bytes, to send to workers through the object store.
    The tar remembers the directory's absolute path, which the datasets record (relocate_source_demos)."""
    if not os.path.isdir(path):
        raise InvalidInputError(f"source demos {path} is not a directory", reason="NO_SOURCE_DEMOS")
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=tarfile.PAX_FORMAT,
                      pax_headers={_ORIGIN: os.path.abspath(path)}) as t:
        t.add(path, arcname="demos")
    return buf.getvalue()


def unpack_dir(data: bytes, dest: str) -> tuple[str, str]:
    """Unpack pack_dir's bytes under `dest`: (the unpacked directory, its path on the driver)."""
    with tarfile.open(fileobj=io.BytesIO(data), mode="r") as t:
        t.extractall(dest, filter="data")
        origin = t.pax_headers.get(_ORIGIN, "")
    return os.path.join(dest, "demos"), origin


def relocate_source_demos(out_dir: str, unpacked: str, origin: str) -> None:
    """Make a shard's env_args name the source demos by their driver paths, as a serial run does,
    not by the worker's temporary copy (the merged dataset then equals the serial run's)."""
    if not origin:
        return
    root = os.path.abspath(unpacked)
    for name in (DATASET_FILE, FAILED_FILE):
        path = os.path.join(out_dir, name)
        if not os.path.exists(path):
            continue
        with h5py.File(path, "a") as f:
            env = json.loads(f["data"].attrs["env_args"])
            gen = env.get("generation", {})
            gen["source_demos"] = [os.path.join(origin, os.path.relpath(p, root)) if p.startswith(root + os.sep)
                                   else p for p in gen.get("source_demos", [])]
            f["data"].attrs["env_args"] = json.dumps(env, sort_keys=True)
