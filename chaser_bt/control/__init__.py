"""Relative-position control (paper section 3.2): PID loops, the follow controller, chase geometry."""

from chaser_bt.control.follow import FollowCommand, FollowConfig, FollowController, ProcessVariables, process_variables
from chaser_bt.control.pid import Pid, PidGains
from chaser_bt.control.sticks import RcSticks, StickMap

__all__ = ["FollowCommand", "FollowConfig", "FollowController", "Pid", "PidGains", "ProcessVariables", "RcSticks",
           "StickMap", "process_variables"]
