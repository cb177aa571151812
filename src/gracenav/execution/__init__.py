"""The hybrid controller (paper Sec. IV-C, V-B), tick by tick, and episodes."""

from gracenav.execution.capture import TerminalPolicy
from gracenav.execution.controller import HybridController
from gracenav.execution.episode import Episode, ExecutionLog, Trace, drive, held_at
from gracenav.execution.smoothness import JerkProfile, jerk_profile
from gracenav.execution.types import (
    CAPTURE,
    TERMINAL,
    Command,
    EventReason,
    ExecutionOptions,
    PlanningMode,
    SwitchEvent,
    TaskStatus,
)

__all__ = [
    "CAPTURE",
    "TERMINAL",
    "Command",
    "Episode",
    "EventReason",
    "ExecutionLog",
    "ExecutionOptions",
    "HybridController",
    "JerkProfile",
    "PlanningMode",
    "SwitchEvent",
    "TaskStatus",
    "TerminalPolicy",
    "Trace",
    "drive",
    "held_at",
    "jerk_profile",
]
