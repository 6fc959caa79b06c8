"""The touch-downs a lift-off predicts (fslip_planner.landing_predictions): planner_node's budget for them
in the flight, and a prediction abandoned for a contact event."""
import numpy as np

from fslip_planner import plan as P
from fslip_planner.landing import PREDICTED_SHIFTS
from fslip_planner.landing_predictions import PredictionBudget


def test_the_prediction_budget_stops_before_a_solve_that_would_end_after_the_planned_touch_down():
    """planner_node's ``stop()`` for the lift-off's predictions: with solves taking 0.1 s of sim time each
    and the touch-down planned 0.45 s after the lift-off, it allows four (the fifth would end at 0.5 s),
    so that the touch-down finds the planner free rather than inside a solve it may not need."""
    clock = [10.0]
    stop = PredictionBudget(lambda: clock[0], 10.0, 10.45)
    solves = 0
    while not stop():
        solves += 1
        clock[0] += 0.1
    assert solves == 4
    assert PredictionBudget(lambda: 10.5, 10.0, 10.45)()      # past the planned touch-down: none


def test_a_prediction_interrupted_by_a_contact_event_is_left_for_the_touch_down():
    """planner_node abandons the prediction under way when a contact event comes (``interrupt``): nothing
    of it is kept, it stays to be solved, and the touch-down's plan is the one every prediction solved
    in the flight gives, to the bit."""
    lift_off = P.MeasuredState(2.0, np.array([0.0, 0.0, 1.0]), np.array([0.21, 0.0, 3.16]), -38.5, -0.05, 0.0,
                               support_center=np.array([0.05, 0.0, 0.0]))
    touch_down = P.MeasuredState(2.65, np.array([0.0, 0.0, 0.95]), np.array([0.20, 0.0, -3.165]), -38.39, 0.0, 0.0,
                                 support_center=np.array([0.086, 0.0, 0.0]))
    plans = []
    for interrupt_at in (None, 25):                 # IPOPT iterations summed over the predictions
        s = P.FlipSession("backflip", apex_height=1.3, motor_speed_scale=3.0, flywheel_torque=260.0)
        s.jumping_reference()
        s.started(1.0)
        s.flight_reference(lift_off)
        calls = []
        interrupt = None if interrupt_at is None else (lambda: calls.append(1) or len(calls) >= interrupt_at)
        s.predict_landing(lift_off, interrupt=interrupt)
        if interrupt_at is not None:
            solved = len(s._landing.solved_states) - 1            # after the nominal
            assert 1 <= solved < len(PREDICTED_SHIFTS) and len(s._predictions.pending) == len(PREDICTED_SHIFTS) - solved
            assert s._landing.interrupt is None                   # only while predicting
        plans.append(s.landing_reference(touch_down))
    assert plans[1].figures["predictions_left"] >= 1.0
    np.testing.assert_array_equal(plans[1].value, plans[0].value)
    np.testing.assert_array_equal(plans[1].t, plans[0].t)
