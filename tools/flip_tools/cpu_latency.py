"""A CPU wake-up latency request (Linux PM QoS, ``/dev/cpu_dma_latency``) held while a graph runs.

Writing a 32-bit integer of microseconds to ``/dev/cpu_dma_latency`` asks the kernel to keep every
CPU in idle states that wake within that time; the request lasts while the file stays open and ends
when it is closed, by this process or by the kernel when the process dies (nothing outlives the run).
With 0 an idle CPU polls instead of halting, so waking a thread on it needs no interrupt; this is the
setting ``cyclictest`` and the usual real-time tuning guides use.

Why the lockstep cares: the simulator and the controller share one CPU, and each step sends three
messages to the recorder, which waits on the other CPU.  On a virtual machine, waking a halted vCPU
costs the sender ~15-20 us a message (docs/architecture.md, Speed).  The request needs write access
to the device (root, as a rule); without it the run goes ahead as before, and says so.
"""
from __future__ import annotations

import os
import struct

DEVICE = "/dev/cpu_dma_latency"


class CpuLatencyRequest:
    """Holds ``/dev/cpu_dma_latency`` at ``us`` microseconds from :meth:`hold` until :meth:`release`.

    ``info()`` says what happened, for run.json: ``{"requested_us", "held", "previous_us"}`` or, when
    the device could not be written, ``{"requested_us", "held": False, "reason"}``; ``us=None``
    requests nothing (``{"requested_us": None, "held": False, "reason": "not requested"}``)."""

    def __init__(self, us: int | None = 0, device: str = DEVICE):
        if us is not None and not (isinstance(us, int) and 0 <= us < 2 ** 31):
            raise ValueError(f"CPU wake-up latency must be an integer of microseconds >= 0, not {us!r}")
        self.us, self.device = us, device
        self._fd = None
        self.previous_us = None
        self.reason = "not requested" if us is None else "not held yet"

    @property
    def held(self) -> bool:
        return self._fd is not None

    def hold(self) -> bool:
        """Open the device and write the request; True when it is in force."""
        if self.us is None or self._fd is not None:
            return self._fd is not None
        try:
            self.previous_us = _read_us(self.device)
            fd = os.open(self.device, os.O_WRONLY)
        except OSError as e:
            self.reason = f"{type(e).__name__}: {e.strerror or e} ({self.device})"
            return False
        try:
            os.write(fd, struct.pack("i", self.us))
        except OSError as e:
            os.close(fd)
            self.reason = f"{type(e).__name__}: {e.strerror or e} ({self.device})"
            return False
        self._fd = fd
        self.reason = None
        return True

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def info(self) -> dict:
        out = {"requested_us": self.us, "held": self.held}
        if self.held:
            out["previous_us"] = self.previous_us
        else:
            out["reason"] = self.reason
        return out

    def __enter__(self):
        self.hold()
        return self

    def __exit__(self, *exc):
        self.release()


def _read_us(device: str) -> int | None:
    """The limit in force now (the device reads as one 32-bit integer), or None if unreadable."""
    try:
        with open(device, "rb") as f:
            raw = f.read(4)
    except OSError:
        return None
    return struct.unpack("i", raw)[0] if len(raw) == 4 else None


def parse_latency(text: str) -> int | None:
    """``--cpu-dma-latency`` value: microseconds (an integer >= 0) or ``off`` (None)."""
    if text.strip().lower() == "off":
        return None
    try:
        us = int(text)
    except ValueError:
        raise ValueError(f"microseconds (0, 10, ...) or 'off', not {text!r}") from None
    if us < 0:
        raise ValueError(f"microseconds must be >= 0, not {us}")
    return us
