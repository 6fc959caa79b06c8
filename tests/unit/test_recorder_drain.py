"""flip_tools.cli.graph.Graph.wait_recorder_drained: `flip` stops its graph once the recorder has written
the simulator's last step.  When the simulator is gone before that step reached the recorder (no /clock
writer matched any more) the step cannot come: the wait ends once the recorder's counts stand still,
not at its 30 s cap (a stand-in run's rejected request took 36 s instead of 7 so)."""
from types import SimpleNamespace

import pytest

from flip_tools.cli import graph as G


class FakeGraph:
    """The parts of Graph the wait reads: the recorder's process, its status (one per spin), sim time;
    each spin advances a fake clock by its timeout (the module's ``time`` is patched to read it)."""
    wait_recorder_drained = G.Graph.wait_recorder_drained

    def __init__(self, statuses, final):
        self.launcher = SimpleNamespace(procs={"recorder": SimpleNamespace(poll=lambda: None)})
        self.recorder_status, self._statuses, self._final = {}, iter(statuses), final
        self.now = 0.0

    def sim_now(self):
        return self._final

    def spin(self, timeout):
        self.now += timeout
        self.recorder_status = next(self._statuses, self.recorder_status)


def status(last_clock_s, clock_writers, odom):
    return {"counts": {"/clock": odom, "/odom": odom}, "matched": {"/clock": clock_writers, "/odom": clock_writers},
            "last_clock_ns": int(round(last_clock_s * 1e9))}


@pytest.fixture
def fake_clock(monkeypatch):
    def make(statuses, final):
        g = FakeGraph(statuses, final)
        monkeypatch.setattr(G, "time", SimpleNamespace(monotonic=lambda: g.now))
        return g
    return make


def test_a_gone_simulator_ends_the_wait_once_the_recorders_queue_is_written(fake_clock, capsys):
    # the recorder is at 0.600 s of 0.605 s and still writing its queue (counts 121..130) when the
    # simulator's writers are gone
    queue = [status(0.600, 0, n) for n in range(121, 131)]
    g = fake_clock([status(0.600, 1, 120)] * 3 + queue, final=0.605)
    g.wait_recorder_drained(timeout=30.0)
    assert next(g._statuses, None) is None                 # every queued count was waited for
    err = capsys.readouterr()
    assert "WARNING" not in err.out + err.err              # ended before the cap
    assert "the simulator is gone" in err.out + err.err


def test_while_the_simulator_is_there_the_last_step_is_waited_for(fake_clock, capsys):
    # counts standing still do not end the wait while a /clock writer is matched: its last step may
    # still be on the way (a loaded machine's recorder stands still for a second)
    g = fake_clock([status(0.600, 1, 120)], final=0.605)
    g.wait_recorder_drained(timeout=30.0)
    err = capsys.readouterr()
    assert "had not written the last step" in err.out + err.err      # waited to the cap
