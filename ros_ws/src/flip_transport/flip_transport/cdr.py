"""Serialized ROS 2 messages (CDR, as rmw_fastrtps writes them) read as numpy arrays, without ROS.

The lockstep's per-step messages are handled as bytes (flip_transport.lockstep): a
``*_layout(buf, names=None)`` function here finds the offsets of a message type's numeric fields,
:func:`fields` makes numpy views of them, :class:`MessageReader` keeps a layout while a stream's
messages keep it.  The bag reader (tools/flip_tools/bag.py) reads whole topics the same way.
"""
from __future__ import annotations

import struct

import numpy as np

# A ``*_layout(buf, names=None)`` function returns ``(names, {field: (offset, count, dtype)})`` for
# one serialized message type: ``names`` its string[] (or None) as CdrCursor.strings gives it, to
# pass back for the next message. Its numeric fields are then read or written as numpy views.

#: a builtin_interfaces/Time (int32 sec, uint32 nanosec) first in the message, after the 4-byte
#: CDR encapsulation header: /clock's stamp and every std_msgs/Header's
_STAMP = struct.Struct('<iI')


def read_stamp_ns(buf):
    """Stamp (ns) of a serialized message that starts with a header or a time."""
    sec, nanosec = _STAMP.unpack_from(buf, 4)
    return sec * 1_000_000_000 + nanosec


_F8, _F4, _U8 = np.dtype('<f8'), np.dtype('<f4'), np.dtype('<u8')
_UINT = {4: struct.Struct('<I'), 8: struct.Struct('<Q')}


class CdrCursor:
    """Walks a serialized ROS 2 message as rmw_fastrtps writes it: little-endian CDR, a 4-byte
    encapsulation header, each field aligned to its size counted from the end of that header."""

    def __init__(self, buf, pos=4):
        self.buf, self.pos = buf, pos

    def _align(self, n):
        self.pos += -(self.pos - 4) % n

    def uint(self, size=4):
        self._align(size)
        v = _UINT[size].unpack_from(self.buf, self.pos)[0]
        self.pos += size
        return v

    def skip_string(self):
        n = self.uint()
        self.pos += n

    def strings(self, known=None):
        """A string[] as ``(names, bytes)``; ``known`` (an earlier result) is skipped by a byte
        compare when the buffer holds the same list here."""
        if known is not None and self.buf[self.pos:self.pos + len(known[1])] == known[1]:
            self.pos += len(known[1])
            return known
        start = self.pos
        names = []
        for _ in range(self.uint()):
            n = self.uint()
            names.append(bytes(self.buf[self.pos:self.pos + n - 1]).decode())
            self.pos += n
        return names, bytes(self.buf[start:self.pos])

    def field(self, dtype, n=None):
        """``(offset, count, dtype)`` of ``n`` values of ``dtype`` here (a sequence: count first;
        an empty one is not aligned)."""
        if n is None:
            n = self.uint()
        if n:
            self._align(dtype.itemsize)
        off = self.pos
        self.pos += n * dtype.itemsize
        return off, n, dtype


def joint_state_layout(buf, names=None):
    """sensor_msgs/JointState: ``(names, {position, velocity, effort})``."""
    c = CdrCursor(buf, 12)
    c.skip_string()                                     # header.frame_id
    names = c.strings(names)
    return names, {'position': c.field(_F8), 'velocity': c.field(_F8), 'effort': c.field(_F8)}


def odometry_layout(buf, names=None):
    """nav_msgs/Odometry: ``(None, {pose, twist})``, pose = position xyz and orientation xyzw,
    twist = linear and angular."""
    c = CdrCursor(buf, 12)
    c.skip_string()                                     # header.frame_id
    c.skip_string()                                     # child_frame_id
    pose = c.field(_F8, 7)
    c.field(_F8, 36)                                    # pose covariance
    return None, {'pose': pose, 'twist': c.field(_F8, 6)}


def motor_command_layout(buf, names=None):
    """flip_msgs/MotorCommand: ``(names, {step, effort, compute_time_us})``."""
    c = CdrCursor(buf, 12)
    c.skip_string()                                     # header.frame_id
    step = c.field(_U8, 1)
    names = c.strings(names)
    return names, {'step': step, 'effort': c.field(_F8), 'compute_time_us': c.field(_F4, 1)}


def wrench_stamped_layout(buf, names=None):
    """geometry_msgs/WrenchStamped: ``(None, {wrench})``, wrench = force xyz and torque xyz."""
    c = CdrCursor(buf, 12)
    c.skip_string()                                     # header.frame_id
    return None, {'wrench': c.field(_F8, 6)}


def fields(buf, layout):
    """Numpy views of ``buf`` for a layout's fields (read-only for ``bytes``)."""
    return {k: np.frombuffer(buf, dtype, n, off) for k, (off, n, dtype) in layout.items()}


class MessageReader:
    """Numpy views of the numeric fields of received serialized messages of one type (``layout``: a
    ``*_layout`` function).  The layout is worked out again only when a message differs from the
    last one outside its numeric fields and stamp, i.e. in its strings or sequence lengths: a 2 kHz
    stream from one publisher keeps the layout of its first message (a byte compare a message,
    instead of walking it).  ``names`` is the string[] of the last layout (as the layout function
    gives it)."""

    def __init__(self, layout):
        self._layout_fn = layout
        self.names = None
        self._size = -1
        self._const = ()         # (start, end, bytes) of the runs outside the numeric fields and stamp
        self._layout = None

    def __call__(self, buf):
        if len(buf) != self._size or any(buf[a:b] != c for a, b, c in self._const):
            self.names, self._layout = self._layout_fn(buf, self.names)
            self._size = len(buf)
            variable = sorted([(4, 12)] + [(off, off + n * dt.itemsize) for off, n, dt in self._layout.values()])
            runs, pos = [], 0
            for a, b in variable:
                if a > pos:
                    runs.append((pos, a, bytes(buf[pos:a])))
                pos = max(pos, b)
            if pos < len(buf):
                runs.append((pos, len(buf), bytes(buf[pos:])))
            self._const = tuple(runs)
        return fields(buf, self._layout)

    def layout(self):
        """The layout of the last message: ``(size, runs, offsets)``: its size in bytes, the byte runs
        outside the numeric fields and stamp as ``(offset, bytes)``, and ``{field: offset}`` (for a
        compiled reader of the same messages, e.g. tsc_controller's StateMap.set_cdr_layout)."""
        if self._layout is None:
            raise ValueError("no message read yet")
        return (self._size, [(a, c) for a, _, c in self._const],
                {k: off for k, (off, _, _) in self._layout.items()})
