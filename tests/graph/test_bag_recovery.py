"""A bag whose recorder was killed (no metadata.yaml, no MCAP summary or index) is recovered: its
whole chunks are read as a streaming reader reads them, the bag is rewritten with its index and
metadata.yaml, and rosbags reads it (issue 26, item 3)."""
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.stream_reader import StreamReader
from mcap.records import Chunk, Message
from rosbags.rosbag2 import Reader

from ros_harness import FLIP, stand_in

from flip_tools.bag import load_bag, recover_bag, scan_mcap


def streamed(path: Path) -> tuple[int, list[str]]:
    """Messages mcap's own streaming reader yields from a (truncated) file before it stops, and the
    compression of the chunks it met."""
    n, comp = 0, []
    with open(path, "rb") as f:
        try:
            for rec in StreamReader(f, skip_magic=False, emit_chunks=True).records:
                if isinstance(rec, Chunk):
                    comp.append(rec.compression)
        except Exception:  # noqa: BLE001 - the cut-off tail
            pass
    with open(path, "rb") as f:
        try:
            for rec in StreamReader(f).records:
                n += isinstance(rec, Message)
        except Exception:  # noqa: BLE001
            pass
    return n, comp


def rosbags_count(bag: Path) -> dict:
    with Reader(bag) as r:
        return {c.topic: c.msgcount for c in r.connections if c.msgcount}


def data_end(data: bytes) -> int:
    """Offset of the Data End record (what follows is the summary a killed writer never wrote)."""
    return data.index(b"\x0f" + (4).to_bytes(8, "little"))


@pytest.mark.parametrize("cut", [0.3, 0.7, 0.99])      # share of the data section left on disk
def test_a_truncated_bag_is_recovered_by_flip_summarize(tmp_path, cut):
    from synthetic_bag import write_flip_bag
    run = tmp_path / "run"
    write_flip_bag(run / "bag", rotation_deg=360.0, final_z=0.9)
    full = rosbags_count(run / "bag")
    mcap = next((run / "bag").glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[:int(data_end(data) * cut)])     # killed mid-write: no summary, no footer
    (run / "bag" / "metadata.yaml").unlink()
    with pytest.raises(Exception):
        Reader(run / "bag").open()
    whole, _ = streamed(mcap)
    assert 0 < whole < sum(full.values())

    r = subprocess.run([sys.executable, str(FLIP), "summarize", str(run), "--kind", "frontflip"],
                       capture_output=True, text=True, timeout=300)
    assert "Traceback" not in r.stderr, r.stderr
    assert (run / "bag" / "metadata.yaml").exists() and sorted(p.name for p in (run / "bag").iterdir()) == [
        "bag.mcap", "metadata.yaml"]
    kept = rosbags_count(run / "bag")
    # every message of a whole chunk, and only those, as mcap's streaming reader reads them
    assert sum(kept.values()) == whole
    assert all(kept[t] <= full[t] for t in kept)
    s = json.loads((run / "summary.json").read_text())
    assert s["bag_recovered"]["messages"] == whole and s["bag_recovered"]["bytes_dropped"] > 0
    assert s["topics"] == {t: kept.get(t, 0) for t in s["topics"]}
    # recovered once: read again as it is
    assert load_bag(run / "bag").recovered is None


def test_recovery_keeps_definitions_qos_and_every_message(tmp_path):
    """A bag cut right after its data (summary and footer lost) reads back the same, message for
    message, with the QoS profiles and message definitions it was written with."""
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "a", rotation_deg=360.0, final_z=0.9)
    mcap = tmp_path / "a" / "a.mcap"
    (tmp_path / "b").mkdir()
    data = mcap.read_bytes()
    (tmp_path / "b" / "b.mcap").write_bytes(data[:data_end(data)])
    info = recover_bag(tmp_path / "b")
    assert info["bytes_dropped"] == 0
    with Reader(tmp_path / "a") as a, Reader(tmp_path / "b") as b:
        ca = {c.topic: c for c in a.connections}
        cb = {c.topic: c for c in b.connections}
        assert ca.keys() == cb.keys()
        for t in ca:
            assert cb[t].msgtype == ca[t].msgtype and cb[t].msgdef == ca[t].msgdef
            assert cb[t].ext.offered_qos_profiles == ca[t].ext.offered_qos_profiles
            assert cb[t].digest == ca[t].digest
        ma = [(c.topic, t, bytes(m)) for c, t, m in a.messages()]
        mb = [(c.topic, t, bytes(m)) for c, t, m in b.messages()]
        assert ma == mb


def test_a_sigkilled_recorder_leaves_whole_zstd_chunks_that_recover(ros_graph, tmp_path):
    bag = tmp_path / "bag"
    ros_graph.start("source", stand_in("source_node.py"), params={"rate": 500.0}, node_name="source_node")
    rec = ros_graph.start("recorder", [sys.executable, str(FLIP), "record", "/motor_command", "--bag", str(bag)])
    ros_graph.expected_exit["recorder"] = {-signal.SIGKILL}
    ros_graph.wait_ready(nodes=["source_node", "flip_recorder"], topics={"/motor_command": (1, 1)})
    mcap = bag / "bag.mcap"
    # until the file holds at least three whole chunks with messages
    ros_graph.test_node.spin_until(lambda: mcap.exists() and len(scan_mcap(mcap)["messages"]) >= 300,
                                   timeout=120, what="three chunks on disk")
    on_disk = len(scan_mcap(mcap)["messages"])
    os.kill(rec.pid, signal.SIGKILL)
    rec.popen.wait(timeout=30)
    assert not (bag / "metadata.yaml").exists()
    whole, comp = streamed(mcap)
    assert whole >= on_disk and comp and set(comp) == {"zstd"}
    info = recover_bag(bag)
    assert info["messages"] == whole and (bag / "metadata.yaml").exists()
    with Reader(bag) as r:
        from flip_tools.typestore import flip_typestore
        store = flip_typestore()
        steps = [store.deserialize_cdr(m, c.msgtype).step for c, _t, m in r.messages()]
    assert len(steps) == whole
    # the source's steps, in the order they were sent
    assert steps == sorted(set(steps))


def _pid_of(arg: str) -> int | None:
    """The process whose command line holds ``arg`` (the recorder of one run's bag)."""
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"record" in cmd and arg.encode() in cmd:
                return int(d.name)
    return None


def test_flip_run_stops_when_its_recorder_dies_and_keeps_what_was_written(tmp_path):
    from test_foundation import _stand_in_exes
    out = tmp_path / "run"
    p = subprocess.Popen([sys.executable, str(FLIP), "run", "backflip", "--duration", "60", "--out", str(out),
                          *_stand_in_exes()], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    mcap = out / "bag" / "bag.mcap"
    try:
        import time
        deadline = time.monotonic() + 240
        while not (mcap.exists() and len(scan_mcap(mcap)["messages"]) >= 200):
            assert p.poll() is None and time.monotonic() < deadline, "the run ended before its bag had data"
            time.sleep(0.2)
        os.kill(_pid_of(str(out / "bag")), signal.SIGKILL)
        stdout, stderr = p.communicate(timeout=240)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 3, stdout + stderr                 # an infrastructure failure
    assert "recorder exited" in stderr and "recovered" in stderr, stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["processes"]["recorder"]["returncode"] == -signal.SIGKILL
    # the simulator was stopped by the tool, not left to run its 60 s
    assert s["processes"]["sim"]["stopped_by"] == "SIGINT"
    assert s["bag_recovered"]["messages"] >= 200 and 0 < s["sim_duration_s"] < 60
    assert sum(rosbags_count(out / "bag").values()) == s["bag_recovered"]["messages"]
