"""flip_tools.tracking: measured outputs against a reference, over the span both cover."""
from pathlib import Path

import numpy as np
import pytest

from flip_tools.tracking import errors_over_plans, newest_reference, output_errors, peak_abs, reference_span


def _ref(domain=3, start=2.0, offset=0.0):
    t = np.linspace(0.0, 1.0, 11)
    value = np.c_[np.zeros_like(t), 0.9 - 0.2 * t, 0.1 * t, np.zeros_like(t)]
    return {"domain": domain, "start_time": start, "t": t, "value": value + offset,
            "output_names": ["H_pitch", "L", "x_com", "phi_pitch"]}


def _measured(ref, dL):
    t = np.arange(0.0, 4.0, 0.005)
    tr = ref["start_time"] + ref["t"]
    L = np.interp(t, tr, ref["value"][:, 1]) + dL(t)
    return {"t": t, "L": L, "x_com": np.interp(t, tr, ref["value"][:, 2]), "H_pitch": np.zeros_like(t)}


def test_errors_are_measured_minus_planned_over_the_common_span():
    ref = _ref()
    m = _measured(ref, lambda t: np.where(t < 2.5, 0.01, -0.03))
    e = output_errors(m, ref, 2.2, 10.0)              # from touch-down at 2.2 s to the reference's end
    assert (e["t0"], e["t1"]) == (2.2, 3.0)
    n_a, n_b = np.sum((m["t"] >= 2.2) & (m["t"] < 2.5)), np.sum((m["t"] >= 2.5) & (m["t"] <= 3.0))
    assert e["L"]["n"] == n_a + n_b
    assert e["L"]["max"] == pytest.approx(0.03)
    assert e["L"]["rms"] == pytest.approx(np.sqrt((n_a * 0.01 ** 2 + n_b * 0.03 ** 2) / (n_a + n_b)), abs=1e-4)     # rounded to 0.1 mm
    assert e["x_com"]["rms"] == pytest.approx(0.0, abs=1e-9) and e["H_pitch"]["max"] == 0.0
    assert "phi_pitch" not in e                        # planned, but not among the measured outputs


def test_no_overlap_gives_none_and_the_newest_reference_wins():
    ref = _ref()
    m = _measured(ref, lambda t: 0.0 * t)
    assert output_errors(m, ref, 3.5, 4.0) is None     # the robot was in the domain after the plan ended
    resolve = _ref(start=2.3, offset=0.05)
    assert newest_reference([_ref(domain=1), ref, resolve], 3) is resolve
    assert newest_reference([ref], 1) is None
    assert reference_span(resolve) == (2.3, 3.3)
    m = _measured(_ref(start=2.3), lambda t: 0.0 * t)  # the robot followed a plan 5 cm shorter in L
    assert output_errors(m, resolve, 2.3, 3.3)["L"]["rms"] == pytest.approx(0.05, abs=1e-4)


def test_a_landing_re_solved_after_a_rebound_is_compared_plan_by_plan():
    """The touch-down's landing plan until the rebound's touch-down re-solve starts, that one after: a
    robot that followed each while it was given has no error, pooled over both (n = all samples); one
    that kept to the first plan shows the second's 5 cm offset from 2.3 s on."""
    first, second = _ref(start=2.0), _ref(start=2.3, offset=0.05)
    t = np.arange(0.0, 4.0, 0.005)
    given = np.where(t < 2.3, np.interp(t, 2.0 + first["t"], first["value"][:, 1]),
                     np.interp(t, 2.3 + second["t"], second["value"][:, 1]))
    m = {"t": t, "L": given, "x_com": np.interp(t, 2.0 + first["t"], first["value"][:, 2]), "H_pitch": 0 * t}
    e = errors_over_plans(m, [second, first], 2.0, 10.0)
    assert e["plans"] == 2 and (e["t0"], e["t1"]) == (2.0, 3.3)
    assert e["L"]["rms"] == pytest.approx(0.0, abs=1e-9) and e["L"]["n"] == np.sum((t >= 2.0) & (t <= 3.3))
    kept = dict(m, L=np.interp(t, 2.0 + first["t"], first["value"][:, 1], right=first["value"][-1, 1]))
    e = errors_over_plans(kept, [first, second], 2.0, 10.0)
    assert e["L"]["max"] >= 0.05 - 1e-9
    assert errors_over_plans(m, [first], 5.0, 6.0) is None


def test_peak_abs_over_a_window():
    t = np.arange(0.0, 1.0, 0.1)
    v = np.sin(10 * t) * 100
    assert peak_abs(t, v, 0.0, 0.25) == pytest.approx(np.max(np.abs(v[:3])))
    assert peak_abs(t, v, 5.0, 6.0) is None


def test_fig6_draws_each_reference_until_the_next_one_starts():
    """A landing re-solved after a rebound replaces the first landing from its start on: the plot
    draws what the controller was given at each time, not two landings over each other."""
    from flip_tools.bag import BagData
    from flip_tools.plots import _ref_series
    refs = [dict(_ref(domain=1, start=1.0), plan_id=1), dict(_ref(domain=3, start=2.0), plan_id=1),
            dict(_ref(domain=3, start=2.3, offset=0.05), plan_id=1),
            dict(_ref(domain=1, start=0.0), plan_id=0)]                   # an older plan: not drawn
    refs = refs[3:] + refs[:3]
    data = BagData(Path("."), topics={"/fslip/reference": {"count": 4}},
                   arrays={"/fslip/reference": {"refs": refs}})
    series = _ref_series(data, "L")
    assert [d for d, _, _ in series] == [1, 3, 3]
    (_, t_jump, _), (_, t_first, _), (_, t_second, L_second) = series
    assert t_jump[-1] <= 2.0 and t_first[0] == 2.0 and t_first[-1] <= 2.3     # cut where the next begins
    assert t_second[0] == pytest.approx(2.3) and t_second[-1] == pytest.approx(3.3)
    assert L_second[0] == pytest.approx(0.95)


def test_fig6_draws_a_landing_pitch_plan_on_the_turn_the_pelvis_is_in():
    """A landing plans the pelvis pitch near 0 rad; after a backflip the pelvis is there at -2pi, and
    the plan is drawn there (not a full turn away from the measured line)."""
    from flip_tools.bag import BagData
    from flip_tools.plots import _plot_ref

    class Ax:
        lines = []

        def plot(self, t, v, *a, **k):
            self.lines.append((np.asarray(t), np.asarray(v)))
    ref = _ref(domain=3, start=2.0)
    ref["value"][:, 3] = 0.05                                   # phi_pitch planned: 0.05 rad
    data = BagData(Path("."), topics={"/fslip/reference": {"count": 1}},
                   arrays={"/fslip/reference": {"refs": [dict(ref, plan_id=1)]}})
    ax = Ax()
    measured = (np.array([0.0, 1.0, 2.0, 4.0]), np.array([0.0, -3.0, -2 * np.pi + 0.1, -2 * np.pi]))
    assert _plot_ref(ax, data, "phi_pitch", turns=measured)
    assert np.allclose(ax.lines[-1][1], 0.05 - 2 * np.pi)
    _plot_ref(ax, data, "phi_pitch")                             # without the measured turn: as planned
    assert np.allclose(ax.lines[-1][1], 0.05)


def test_scene_draws_the_crouch_lift_off_apex_touch_down_and_end():
    from flip_tools.bag import BagData
    from flip_tools.plots import scene_instants
    arrays = {"/odom": {"t": np.arange(0.0, 5.0, 0.0005)},
              "/contact_events": {"t": np.array([2.0, 2.6, 2.7, 2.72]), "event": np.array([0, 1, 0, 1])}}
    data = BagData(Path("."), topics={k: {"count": 1} for k in arrays}, arrays=arrays)
    assert scene_instants(data) == [("crouch", 1.7), ("lift-off", 2.0), ("mid-flight", 2.3), ("touch-down", 2.6),
                                    ("end", pytest.approx(4.9995))]
    arrays["/contact_events"] = {"t": np.zeros(0), "event": np.zeros(0)}     # a stand: no flight
    assert [k for k, _ in scene_instants(data)] == ["start", "end"]
