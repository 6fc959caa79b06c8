"""flip_tools.cpu_latency: the PM QoS request `flip` holds while a graph runs."""
from __future__ import annotations

import struct
import subprocess
import sys

import pytest

from ros_harness import FLIP

from flip_tools.cpu_latency import CpuLatencyRequest, parse_latency


def test_request_written_while_held_and_released(tmp_path):
    dev = tmp_path / "cpu_dma_latency"           # a file in the device's place: what is written, read
    dev.write_bytes(struct.pack("i", 2_000_000_000))
    req = CpuLatencyRequest(0, device=str(dev))
    with req:
        assert req.held
        assert dev.read_bytes()[:4] == struct.pack("i", 0)
        assert req.info() == {"requested_us": 0, "held": True, "previous_us": 2_000_000_000}
    assert not req.held                          # the descriptor is closed: the kernel drops the request
    req2 = CpuLatencyRequest(25, device=str(dev))
    assert req2.hold() and struct.unpack("i", dev.read_bytes()[:4])[0] == 25
    req2.release()


def test_request_without_the_device_says_why_and_does_not_raise(tmp_path):
    req = CpuLatencyRequest(0, device=str(tmp_path / "missing"))
    assert req.hold() is False and not req.held
    info = req.info()
    assert info["held"] is False and "FileNotFoundError" in info["reason"]
    req.release()                                # nothing to release: no error
    off = CpuLatencyRequest(None, device=str(tmp_path / "missing"))
    assert off.hold() is False and off.info() == {"requested_us": None, "held": False, "reason": "not requested"}


def test_latency_values():
    assert parse_latency("off") is None and parse_latency("OFF") is None
    assert parse_latency("0") == 0 and parse_latency("15") == 15
    for bad in ("-1", "fast", "1.5"):
        with pytest.raises(ValueError):
            parse_latency(bad)
    with pytest.raises(ValueError):
        CpuLatencyRequest(-3)


def test_flip_refuses_a_bad_latency_before_starting_anything():
    r = subprocess.run([sys.executable, str(FLIP), "stand", "--duration", "1", "--out", "/nonexistent/x",
                        "--cpu-dma-latency", "soon"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "--cpu-dma-latency" in r.stderr and "'soon'" in r.stderr
