"""Package exceptions.

Every error a user can cause (a bad file, a bad argument, an impossible goal,
a stale cache) is raised as a subclass of :class:`GracenavError`, whose
message says what is wrong and what to do. Each also subclasses the matching
built-in exception so callers may catch either.
"""

from __future__ import annotations

__all__ = [
    "CacheError",
    "ConfigError",
    "GracenavError",
    "MapError",
    "OutputError",
    "PlanningError",
]


class GracenavError(Exception):
    """Base class of every gracenav error a user can cause."""


class ConfigError(GracenavError, ValueError):
    """A parameter, option or scenario value is missing, unknown or invalid."""


class MapError(GracenavError, ValueError):
    """A map file or inline map description is malformed."""


class CacheError(GracenavError, RuntimeError):
    """A cached data file is stale, corrupt or does not match its key."""


class PlanningError(GracenavError, RuntimeError):
    """A navigation goal is impossible (obstacle, outside the map or coverage, unreachable)."""


class OutputError(GracenavError, OSError):
    """An output location cannot be used: it is a file, cannot be written, or another
    run is writing to it."""
