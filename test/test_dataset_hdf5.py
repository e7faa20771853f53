"""robomimic-layout HDF5: layout validation, readers by key, determinism, crash safety."""
import hashlib
import json
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest
from _generation_fakes import FakeTask, FakeWorld, make_source_demos

from skillgen_ros.core.dataset.hdf5 import LABEL_KEYS, OBS_KEYS, DatasetError, DatasetWriter, validate_dataset
from skillgen_ros.core.dataset.sink import AttemptSink, make_env_args
from skillgen_ros.core.generation.attempt import GenerationConfig, run_attempt

TASK = FakeTask()
CFG = GenerationConfig(variant="D1")


@pytest.fixture(scope="module")
def demos():
    return make_source_demos(3)


def generate(out_dir, demos, seed=7, n=4, worlds=None, keep_timings=False):
    env_args = make_env_args(TASK.name, "D1", "skillgen", seed, CFG, ["cube", "plate"])
    with AttemptSink(str(out_dir), env_args, keep_timings=keep_timings) as sink:
        for i in range(n):
            world = worlds(i) if worlds else FakeWorld(images=True)
            sink.add(run_attempt(world, demos, TASK, "skillgen", i, seed, CFG))
    return sink


def test_layout_and_robomimic_style_reading(tmp_path, demos):
    sink = generate(tmp_path, demos, worlds=lambda i: FakeWorld(images=True, plan_status="OK" if i % 2 else "IK_FAILED"))
    summary = validate_dataset(sink.dataset_path)
    assert summary.num_demos == 2 and summary.filter_keys["successful"] == 2
    assert summary.env_args["env_name"] == "pick_place"
    failed = validate_dataset(sink.failed_path)
    assert failed.filter_keys == {"IK_FAILED": 2}
    assert sink.counts == {"OK": 2, "IK_FAILED": 2}
    with h5py.File(sink.dataset_path, "r") as f:  # the way robomimic's SequenceDataset reads
        demos_ = sorted(f["data"].keys(), key=lambda k: int(k[5:]))
        assert demos_ == ["demo_0", "demo_1"]
        json.loads(f["data"].attrs["env_args"])
        total = 0
        for d in demos_:
            g = f[f"data/{d}"]
            T = int(g.attrs["num_samples"])
            total += T
            for k in OBS_KEYS + ("front_image",):
                assert g[f"obs/{k}"].shape[0] == T
            assert g["obs/front_image"].dtype == np.uint8 and g["obs/front_image"].shape[1:] == (8, 8, 3)
            for k in LABEL_KEYS:
                assert g[f"labels/{k}"].shape[0] == T
            assert g["actions"].shape == (T, 7) and g["actions_abs"].shape == (T, 8)
            assert g["rewards"][-1] == 1 and g["dones"][-1] == 1 and g["states"].shape[0] == T
            assert g.attrs["reason"] == "OK" and g.attrs["method"] == "skillgen"
        assert total == f["data"].attrs["total"]
        assert [n.decode() for n in f["mask/successful"][()]] == demos_
    with h5py.File(sink.failed_path, "r") as f:
        assert f["data/demo_0"].attrs["reason"] == "IK_FAILED"


def test_same_seed_same_bytes(tmp_path, demos):
    a = generate(tmp_path / "a", demos)
    b = generate(tmp_path / "b", demos)
    c = generate(tmp_path / "c", demos, seed=8)
    digest = lambda p: hashlib.sha256(open(p, "rb").read()).hexdigest()  # noqa: E731
    assert digest(a.dataset_path) == digest(b.dataset_path) != digest(c.dataset_path)
    t1 = generate(tmp_path / "t1", demos, keep_timings=True)  # timings differ; arrays do not
    with h5py.File(a.dataset_path, "r") as fa, h5py.File(t1.dataset_path, "r") as fb:
        for d in fa["data"]:
            for k in ("actions", "actions_abs", "states", "obs/object", "labels/initiation_target"):
                np.testing.assert_array_equal(fa[f"data/{d}/{k}"][()], fb[f"data/{d}/{k}"][()])


def test_writer_refuses_existing_and_unwritable(tmp_path, demos):
    sink = generate(tmp_path, demos, n=1)
    before = open(sink.dataset_path, "rb").read()
    with pytest.raises(DatasetError) as e:
        DatasetWriter(sink.dataset_path, {})
    assert e.value.reason == "OUTPUT_EXISTS"
    assert open(sink.dataset_path, "rb").read() == before  # untouched
    other = tmp_path / "other"
    other.mkdir()
    (other / "failed.hdf5").write_bytes(b"keep")
    with pytest.raises(DatasetError) as e:
        AttemptSink(str(other), {})
    assert e.value.reason == "OUTPUT_EXISTS" and sorted(p.name for p in other.iterdir()) == ["failed.hdf5"]
    blocker = tmp_path / "a_file"  # a directory path through a regular file cannot be created, even by root
    blocker.write_text("x")
    with pytest.raises(DatasetError) as e:
        DatasetWriter(str(blocker / "out" / "x.hdf5"), {})
    assert e.value.reason == "OUTPUT_NOT_WRITABLE"
    # append mode continues the numbering and the total
    r = run_attempt(FakeWorld(), demos, TASK, "skillgen", 5, 7, CFG)
    with DatasetWriter(sink.dataset_path, {}, mode="append") as w:
        assert w.append(r.episode, {"reason": "OK"}, ["successful"]) == "demo_1"
    s = validate_dataset(sink.dataset_path)
    assert s.num_demos == 2 and s.filter_keys["successful"] == 2


def test_crash_leaves_valid_file(tmp_path):
    """A writer process killed mid-run (no close) leaves every flushed demo readable."""
    path = tmp_path / "crash.hdf5"
    code = textwrap.dedent(f"""
        import os, sys
        sys.path.insert(0, {str(__import__('pathlib').Path(__file__).parent)!r})
        from _generation_fakes import FakeTask, FakeWorld, make_source_demos
        from skillgen_ros.core.dataset.hdf5 import DatasetWriter
        from skillgen_ros.core.generation.attempt import run_attempt, GenerationConfig
        demos = make_source_demos(2)
        w = DatasetWriter({str(path)!r}, {{"env_name": "pick_place"}})
        for i in range(3):
            w.append(run_attempt(FakeWorld(), demos, FakeTask(), "skillgen", i, 1, GenerationConfig()).episode,
                     {{}}, ["successful"])
        os._exit(1)  # die without closing the file
    """)
    assert subprocess.run([sys.executable, "-c", code]).returncode == 1
    s = validate_dataset(str(path))
    assert s.num_demos == 3 and s.filter_keys["successful"] == 3


def test_validator_catches_broken_layouts(tmp_path, demos):
    sink = generate(tmp_path, demos, n=1)
    p = sink.dataset_path

    def broken(mutate):
        q = tmp_path / f"b{np.random.randint(1e9)}.hdf5"
        q.write_bytes(open(p, "rb").read())
        with h5py.File(q, "a") as f:
            mutate(f)
        return str(q)

    cases = [
        lambda f: f["data"].attrs.__setitem__("total", 3),
        lambda f: f["data"].attrs.__delitem__("env_args"),
        lambda f: f["data/demo_0"].__delitem__("labels/mp_step"),
        lambda f: f["data/demo_0"].__delitem__("obs/robot0_eef_pos"),
        lambda f: f["data/demo_0"].attrs.__setitem__("num_samples", 2),
        lambda f: f["mask"].create_dataset("x", data=np.array([b"demo_9"])),
        lambda f: f["data/demo_0/actions"].__setitem__((0, 0), 5.0),
    ]
    for mutate in cases:
        with pytest.raises(DatasetError):
            validate_dataset(broken(mutate))
    bad = tmp_path / "junk.hdf5"
    bad.write_bytes(b"not hdf5")
    with pytest.raises(DatasetError):
        validate_dataset(str(bad))


def test_shards_merge_to_the_single_run(tmp_path, demos):
    from skillgen_ros.core.dataset.hdf5 import merge_datasets, read_episode
    from skillgen_ros.core.generation.seeds import shard_indices

    env_args = make_env_args(TASK.name, "D1", "skillgen", 4, CFG, ["cube", "plate"])

    def run(out, indices):
        with AttemptSink(str(out), env_args, keep_timings=False) as sink:
            for i in indices:
                sink.add(run_attempt(FakeWorld(), demos, TASK, "skillgen", i, 4, CFG))
        return sink.dataset_path

    single = run(tmp_path / "single", range(6))
    shards = [run(tmp_path / f"s{k}", shard_indices(0, 6, k, 2)) for k in range(2)]
    merged = merge_datasets(shards, str(tmp_path / "merged.hdf5"))
    assert merged.num_demos == 6 and merged.filter_keys["successful"] == 6
    with h5py.File(single, "r") as fa, h5py.File(merged.path, "r") as fb:
        def items(f):
            out = {}
            f.visititems(lambda k, v: out.__setitem__(k, v[()].tobytes() if isinstance(v, h5py.Dataset) else None))
            return out
        assert items(fa) == items(fb)
        for d in fa["data"]:
            assert dict(fa["data"][d].attrs).keys() == dict(fb["data"][d].attrs).keys()
            assert fa["data"][d].attrs["index"] == fb["data"][d].attrs["index"]
    ep, attrs = read_episode(single, "demo_2")
    assert attrs["index"] == 2 and ep.object_ids == ("cube", "plate") and ep.num_samples > 0


def test_a_long_writer_reopens_its_file_and_stays_valid(tmp_path, monkeypatch):
    """issue 19's soak: the writer closes and reopens its file every REOPEN_EVERY demos (HDF5's
    per-open-file metadata grew ~0.1 MiB per demo); order, masks and totals carry across."""
    import skillgen_ros.core.dataset.hdf5 as h5mod

    monkeypatch.setattr(h5mod, "REOPEN_EVERY", 3)
    ep = run_attempt(FakeWorld(), make_source_demos(2), TASK, "skillgen", 0, 7, CFG).episode
    path = tmp_path / "demo.hdf5"
    w = DatasetWriter(str(path), {"env_name": "pick_place"})
    opened = [w._f]  # the File objects themselves (kept alive: an id could be reused)
    for i in range(8):
        w.append(ep, {"index": i}, ["successful"])
        if w._f is not opened[-1]:
            opened.append(w._f)
    w.close()
    assert len(opened) == 3  # opened once, reopened after demos 3 and 6
    summary = validate_dataset(str(path))
    assert summary.num_demos == 8 and summary.filter_keys["successful"] == 8 and summary.total == 8 * ep.num_samples
    with h5py.File(path, "r") as f:
        assert list(f["data"].keys()) == [f"demo_{i}" for i in range(8)]  # creation order kept
        assert [int(f["data"][k].attrs["index"]) for k in f["data"]] == list(range(8))
