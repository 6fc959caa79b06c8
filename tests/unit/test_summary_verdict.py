"""The summary verdict and plots of a run, from synthetic bags written with rosbags
(tests/synthetic_bag.py): real-time factor, per-step topic counts, landing checks, outcomes."""
from __future__ import annotations

import json
from pathlib import Path

import pytest


@pytest.mark.parametrize("head", [0, 4])
def test_summary_real_time_factor_ignores_resent_first_and_last_states(tmp_path, head):
    """Copies of the last state that come after the last step (a lockstep simulator re-sending it)
    are not stepping time: the factor runs to the last step's first arrival; nor are the copies of
    the first state sent before the controller answered it (start-up, reported apart as
    first_state_wait_s): it runs from that state's last arrival."""
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "bag", rotation_deg=360.0, final_z=0.9, resent_tail=10, resent_head=head)
    s = summarize_bag(tmp_path / "bag", kind="frontflip")
    assert s["sim_time_source"] == "/odom" and s["real_time_factor"] == pytest.approx(0.5, rel=1e-3)
    assert s["first_state_wait_s"] == pytest.approx(0.05 * head, abs=1e-6)
    assert s["sim_duration_s"] == pytest.approx(1.0 + 0.3 + 0.6 + 0.4 + 1.5, abs=0.01)


def test_summary_counts_each_per_step_topic_from_the_first_step(tmp_path):
    """summary.json's recorded_steps: /odom, /joint_states and /motor_command against the steps
    simulated from step 0 (a run that lost its first commands shows it), and a verdict note names
    the first step a topic misses."""
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    tr = write_flip_bag(tmp_path / "whole", dt=0.0005, rotation_deg=360.0, final_z=0.9)
    n = len(tr["t"])
    s = summarize_bag(tmp_path / "whole", kind="frontflip")
    assert s["recorded_steps"]["/odom"] == {"recorded": n, "expected": n, "fraction": 1.0, "first_missing": None}
    assert s["recorded_steps"]["/motor_command"]["first_missing"] is None
    assert not any("not in the bag" in x for x in s["verdict_notes"])
    write_flip_bag(tmp_path / "holes", dt=0.0005, rotation_deg=360.0, final_z=0.9, drop_joint_states=(0, 7, 8))
    s = summarize_bag(tmp_path / "holes", kind="frontflip")
    assert s["recorded_steps"]["/joint_states"] == {"recorded": n - 3, "expected": n,
                                                    "fraction": round((n - 3) / n, 5), "first_missing": 0}
    assert f"/joint_states: 3 of {n} steps not in the bag (the first: step 0)" in s["verdict_notes"]


def test_summary_frontflip_landed(tmp_path):
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "bag", rotation_deg=360.0, final_z=0.9)
    s = summarize_bag(tmp_path / "bag", kind="frontflip")
    assert s["outcome"] == "landed", s
    assert s["net_rotation_deg"] == pytest.approx(360.0, abs=1.0)
    assert s["net_rotation_integrated_deg"] == pytest.approx(360.0, abs=5.0)
    assert s["final_tilt_deg"] < 1.0 and s["final_height_above_ground_m"] == pytest.approx(0.9, abs=1e-3)
    assert s["at_rest"] is True
    assert s["flight_time_s"] == pytest.approx(0.6, abs=2e-3)
    assert s["forward_distance_m"] == pytest.approx(0.4, abs=1e-3)
    assert s["apex_pelvis_z_m"] == pytest.approx(1.0 + 9.81 * 0.6 ** 2 / 8, abs=5e-3)
    assert s["sim_duration_s"] == pytest.approx(1.0 + 0.3 + 0.6 + 0.4 + 1.5, abs=0.01)
    assert s["real_time_factor"] == pytest.approx(0.5, rel=1e-3)
    assert 100 <= s["tsc_tick_us"]["median"] <= 200 and s["tsc_tick_us"]["p99"] >= 197
    assert s["peak_flywheel_rpm"] > 0 and s["peak_flywheel_torque_nm"] > 0
    assert s["peak_motor_torque_nm"]["right_foot"] == pytest.approx(9.0)
    assert s["planner"]["solve_time_s"] == [0.42]
    assert s["planner"]["start_time_s"] is None                          # a flight reference only, no jump
    assert s["checks"]["only_feet_touch_ground"]["ok"] is True       # no BODY_CONTACT event
    assert s["checks"]["touchdown_on_landing_ground"]["ok"] is True   # the feet came down at z = 0.02
    assert s["tsc_tick_us"]["n"] == s["motor_commands"] and "tsc_tick_us_note" not in s
    assert s["unverified"] == []
    # the pelvis at lift-off and touch-down: a pure pitch flip, nothing picked up off the y axis
    assert s["liftoff_state"]["t"] == pytest.approx(s["liftoff_time_s"]) and s["liftoff_state"]["rotation_deg"] == 0.0
    assert s["touchdown_state"]["rotation_deg"] == pytest.approx(360.0, abs=0.5)
    assert s["touchdown_state"]["axis_tilt_deg"] == 0.0 and s["touchdown_state"]["transverse_rate_radps"] == 0.0
    json.dumps(s)  # serialisable as is


def test_summary_expects_the_turns_of_every_flip_the_planner_started(tmp_path):
    """Two backflips on one running graph (`flip run backflip --duration`, then `flip request
    backflip`): the bag's two JUMPING references ask -360 deg each, so -720 deg is a landing, not an
    over-rotation of the run's first backflip; one started flip that turned twice is over-rotated,
    and a backflip followed by a frontflip expects no net turn."""
    import math
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "two", rotation_deg=-720.0, final_z=0.9, jumping_turns=(-2 * math.pi, -2 * math.pi))
    s = summarize_bag(tmp_path / "two", kind="backflip")
    assert s["outcome"] == "landed" and s["flips_started"] == 2, s
    assert s["checks"]["rotation"]["expected_deg"] == pytest.approx(-720.0)
    write_flip_bag(tmp_path / "one", rotation_deg=-720.0, final_z=0.9, jumping_turns=(-2 * math.pi,))
    s = summarize_bag(tmp_path / "one", kind="backflip")
    assert s["outcome"] == "over_rotated" and s["flips_started"] == 1, s
    write_flip_bag(tmp_path / "mixed", rotation_deg=-360.0, final_z=0.9, jumping_turns=(-2 * math.pi, 2 * math.pi))
    s = summarize_bag(tmp_path / "mixed", kind="backflip")
    assert s["checks"]["rotation"]["expected_deg"] == pytest.approx(0.0) and s["outcome"] == "over_rotated", s
    write_flip_bag(tmp_path / "old", rotation_deg=-720.0, final_z=0.9)      # no JUMPING reference: the kind's
    s = summarize_bag(tmp_path / "old", kind="backflip")
    assert s["flips_started"] is None and s["checks"]["rotation"]["expected_deg"] == -360.0


def test_summary_touchdown_state_shows_the_yaw_a_flip_picked_up(tmp_path):
    """A flip that yaws 8 deg in the air: the bag-only summary reports it at touch-down (the pelvis y
    axis, about which a somersault turns, 8 deg off world y), not at lift-off."""
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "bag", rotation_deg=360.0, final_z=0.9, flight_yaw_deg=8.0)
    s = summarize_bag(tmp_path / "bag", kind="frontflip")
    assert s["liftoff_state"]["axis_tilt_deg"] == pytest.approx(0.0, abs=0.01)
    assert s["touchdown_state"]["axis_tilt_deg"] == pytest.approx(8.0, abs=0.05)
    assert s["touchdown_state"]["transverse_rate_radps"] > 0.05
    assert s["touchdown_state"]["rotation_deg"] == pytest.approx(360.0, abs=1.0)
    assert s["touchdown_com_ahead_of_feet_m"] == pytest.approx(-0.2)   # the bag's feet, 0.2 m ahead
    assert s["outcome"] == "landed"         # a diagnostic, not a landing criterion


def test_summary_touchdown_elsewhere_than_on_the_landing_ground(tmp_path):
    """Flip D's landing area is raised to z = 0.1: a flip whose feet came down at the ground it took
    off from (support centre z = 0.02) did not land on it, however upright it ends."""
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "bag", rotation_deg=360.0, final_z=0.9)
    s = summarize_bag(tmp_path / "bag", kind="frontflip", landing_ground_z=0.1)
    assert s["touchdown_support_z_m"] == pytest.approx(0.02)
    assert s["checks"]["touchdown_on_landing_ground"]["ok"] is False
    assert s["checks"]["final_height"]["ok"] is True and s["at_rest"] is True
    assert s["outcome"] == "off_landing_ground"
    # a bag without a touch-down cannot tell: unknown, not a verdict
    write_flip_bag(tmp_path / "bag2", contact_events=False, rotation_deg=360.0, final_z=0.9)
    s2 = summarize_bag(tmp_path / "bag2", kind="frontflip", landing_ground_z=0.1)
    assert s2["checks"]["touchdown_on_landing_ground"]["ok"] is None
    assert "touchdown_on_landing_ground" in s2["unverified"]


def test_flip_requests_a_distance_that_reaches_the_landing_ground():
    """A platform flip (C) and a flip onto the raised landing area (D) get the forward distance that
    takes them off the platform / onto the area unless --distance says otherwise."""
    from types import SimpleNamespace as NS
    from cassie_model.model import Scenario
    from flip_tools.flip_request import PLATFORM_FLIP_DISTANCE, RAISED_FLIP_DISTANCE, request_distance
    assert request_distance(NS(distance=None, platform=None, ground_offset=None)) == 0.0
    assert request_distance(NS(distance=None, platform=0.5, ground_offset=None)) == PLATFORM_FLIP_DISTANCE
    assert request_distance(NS(distance=None, platform=None, ground_offset=0.1)) == RAISED_FLIP_DISTANCE
    assert request_distance(NS(distance=0.3, platform=None, ground_offset=0.1)) == 0.3
    # the heels of a robot that stood with them at x = -0.1 come down past the raised area's edge
    assert RAISED_FLIP_DISTANCE - 0.1 > Scenario.raised_landing(0.1).landing_start_x


def test_summary_body_contact_and_unknown(tmp_path):
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    # upright at the end, but a knee touched the ground at landing: not a landing
    write_flip_bag(tmp_path / "knee", rotation_deg=360.0, body_contact_at=2.0)
    s = summarize_bag(tmp_path / "knee", kind="frontflip")
    assert s["outcome"] == "body_contact"
    assert s["checks"]["only_feet_touch_ground"] == {"ok": False, "contacts": [{"t": 2.0, "bodies": "left_knee"}],
                                                     "note": "BODY_CONTACT events after the first lift-off"}
    # after a fall the controller only damps: the tick statistics are those of the commands before it
    assert 0 < s["tsc_tick_us"]["n"] < s["motor_commands"]
    assert s["tsc_tick_us_note"] == f"the {s['tsc_tick_us']['n']} commands before the first BODY_CONTACT"
    # no /contact_events in the bag: the summary says it cannot tell, it does not guess
    write_flip_bag(tmp_path / "noev", rotation_deg=360.0, contact_events=False)
    s = summarize_bag(tmp_path / "noev", kind="frontflip")
    assert s["checks"]["only_feet_touch_ground"]["ok"] is None
    assert "only_feet_touch_ground" in s["unverified"] and s["flight_time_s"] is None
    assert s["outcome"] == "landed"      # decided on what the bag does show


def test_summary_backflip_sign_and_fell(tmp_path):
    from flip_tools.summary import summarize_bag
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "back", rotation_deg=-360.0, final_z=0.9)
    s = summarize_bag(tmp_path / "back", kind="backflip")
    assert s["outcome"] == "landed" and s["net_rotation_deg"] == pytest.approx(-360.0, abs=1.0)
    # the same backflip judged as a frontflip is not a landing
    assert summarize_bag(tmp_path / "back", kind="frontflip")["outcome"] != "landed"

    write_flip_bag(tmp_path / "fell", rotation_deg=360.0, final_z=0.9, final_tilt_deg=90.0)
    s = summarize_bag(tmp_path / "fell", kind="frontflip")
    assert s["outcome"] == "fell", s
    assert s["final_tilt_deg"] == pytest.approx(90.0, abs=1.0)
    assert s["checks"]["final_tilt"]["ok"] is False


def test_plots_from_synthetic_bag(tmp_path):
    from flip_tools.plots import plot_bag
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "bag", rotation_deg=-360.0)
    files = plot_bag(tmp_path / "bag", tmp_path)
    assert files and all(Path(f).stat().st_size > 1000 for f in files)


def test_landing_fallbacks_are_read_from_the_controller_log(tmp_path):
    """summary.json's landing_fallbacks: tsc_node's 'landing fallback' warnings, in order; none in a
    log without them; None without a log."""
    from flip_tools.cli.results import landing_fallbacks
    log = tmp_path / "tsc.log"
    log.write_text("[INFO] [tsc_node]: reference: plan 1 domain 3\n"
                   "[WARN] [1.2] [tsc_node]: landing fallback: own landing from t=2.0530 s (rebound)\n"
                   "[WARN] [1.9] [tsc_node]: landing fallback: own landing from t=4.1000 s (no landing plan)\n")
    assert landing_fallbacks(log) == [{"t": 2.053, "reason": "rebound"}, {"t": 4.1, "reason": "no landing plan"}]
    log.write_text("[INFO] [tsc_node]: reference: plan 1 domain 3\n")
    assert landing_fallbacks(log) == []
    assert landing_fallbacks(tmp_path / "missing.log") is None


def test_landing_rebounds_are_read_from_the_controller_log(tmp_path):
    """summary.json's landing_rebounds: the times of tsc_node's 'rebound at t=' lines (the plan went on
    until the next touch-down's re-solve), in order; [] without them; None without a log."""
    from flip_tools.cli.results import landing_rebounds
    log = tmp_path / "tsc.log"
    log.write_text("[INFO] [tsc_node]: reference: plan 1 domain 3\n"
                   "[INFO] [1.2] [tsc_node]: rebound at t=4.3825 s: the landing plan goes on until the next "
                   "touch-down is re-solved\n")
    assert landing_rebounds(log) == [4.3825]
    log.write_text("[INFO] [tsc_node]: reference: plan 1 domain 3\n")
    assert landing_rebounds(log) == []
    assert landing_rebounds(tmp_path / "missing.log") is None
