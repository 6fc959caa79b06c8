"""The controller's domains and its references: :class:`Domain` (flip_msgs numbering) and
:class:`SampledReference`, a flip_msgs/FlipReference in plain Python (no ROS), sampled per tick."""
from __future__ import annotations

from enum import IntEnum

import numpy as np


class Domain(IntEnum):
    STANDING = 0
    JUMPING = 1
    FLIGHT = 2
    LANDING = 3


class SampledReference:
    """A FlipReference in plain Python: samples ``t`` (s from start_time) x ``names``.

    ``value``, ``d_value``, ``dd_value`` are (len(t), len(names)) (or flat row-major, as in the message).
    """

    def __init__(self, domain, t, names, value, d_value=None, dd_value=None, start_time=0.0,
                 plan_id=0, parameters=None):
        self.domain = Domain(int(domain))
        self.t = np.asarray(t, float)
        self.names = list(names)
        n, k = len(self.t), len(self.names)

        def arr(x):
            return np.zeros((n, k)) if x is None or len(x) == 0 else np.asarray(x, float).reshape(n, k)
        self.value, self.d_value, self.dd_value = arr(value), arr(d_value), arr(dd_value)
        self._rows = np.concatenate((self.value, self.d_value, self.dd_value), axis=1)   # sampled at once
        self.start_time = float(start_time)
        self.plan_id = int(plan_id)
        self.parameters = dict(parameters or {})
        self._col = {nm: i for i, nm in enumerate(self.names)}

    @classmethod
    def from_msg(cls, msg):
        """From a flip_msgs/FlipReference (duck-typed; no ROS import here), as tsc_node reads one.

        ``value``, ``d_value`` and ``dd_value`` must each hold len(t) x len(output_names) samples (the
        message's layout; an empty derivative is malformed too): ValueError otherwise, as for a domain
        that is not one.  ``start_time`` is the stamp's integer nanoseconds times 1e-9, the way the
        controller's tick time is formed from a state's stamp (sec + 1e-9 nanosec differs from it in
        the last bit for about a third of stamps; one bit above it, a JUMPING reference would start a
        step late)."""
        shape = (len(msg.t), len(msg.output_names))
        st = msg.start_time
        return cls(msg.domain, msg.t, msg.output_names, np.asarray(msg.value).reshape(shape),
                   np.asarray(msg.d_value).reshape(shape), np.asarray(msg.dd_value).reshape(shape),
                   (st.sec * 1_000_000_000 + st.nanosec) * 1e-9, msg.plan_id,
                   dict(zip(msg.parameter_names, msg.parameter_values)))

    @property
    def duration(self):
        return float(self.t[-1]) if len(self.t) else 0.0

    def has(self, name):
        return name in self._col

    def sample(self, tau):
        """{name: (value, d_value, dd_value)} at tau (s from the reference's origin), clamped to the ends."""
        t = self.t
        if tau <= t[0]:
            i, a = 0, 0.0
        elif tau >= t[-1]:
            i, a = len(t) - 2, 1.0
        else:
            i = int(np.searchsorted(t, tau)) - 1
            a = (tau - t[i]) / (t[i + 1] - t[i])
        R = self._rows
        row = (R[0] if len(t) == 1 else (1 - a) * R[i] + a * R[i + 1]).tolist()
        k = len(self.names)
        return {nm: (row[c], row[k + c], row[2 * k + c]) for nm, c in self._col.items()}
