"""tsc_controller: momentum-included task space control (Xiong & Ames, §V) for Cassie + flywheel.

Plain-Python core (no ROS): :mod:`dynamics` (Pinocchio terms), :mod:`outputs` (paper §V-A),
:mod:`tsc` and :mod:`limits` (the torque-only QP of §V-B), :mod:`domains` (domain switching and the
:class:`Controller` facade), the domains' objects (:mod:`standing`, :mod:`jumping`, :mod:`flight`,
:mod:`landing`, their shared :mod:`ground_targets`, :mod:`domain_outputs`), :mod:`reference`
(:class:`Domain`, :class:`SampledReference`), :mod:`profiles` (quintic and leg-catch profiles),
:mod:`config` (:class:`ControllerConfig`, its overrides from JSON), :mod:`state` (contract arrays -> q, v).
"""
from .config import ControllerConfig  # noqa: F401
from .domains import Controller  # noqa: F401
from .dynamics import MOTOR_NAMES  # noqa: F401
from .reference import Domain, SampledReference  # noqa: F401
from .state import StateConverter, state_from_ros  # noqa: F401
