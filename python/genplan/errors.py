"""The errors genplan raises for a caller's bad input, one class per kind of problem.

Every class is a subclass of :class:`GenplanError`, itself a subclass of :class:`ValueError`, so
``except ValueError`` keeps working while tests and callers can match the kind by type::

    from genplan.errors import UnknownNameError
    try:
        robot.link_poses(q, ["no_such_link"])
    except UnknownNameError as exc:
        print(exc)          # unknown link 'no_such_link' (known: ...)

The native core raises the same classes (``genplan._core`` looks them up here), so an error has
one type whichever layer found it. A file that does not exist raises the standard
:class:`FileNotFoundError`; a file that exists but cannot be used raises :class:`RobotFileError`,
:class:`TaskFileError`, :class:`SceneFileError`, :class:`ModelFileError` or
:class:`DataFileError`. See docs/ARCHITECTURE.md ("Errors").
"""

from __future__ import annotations

__all__ = [
    "CallbackError",
    "DataFileError",
    "GenplanError",
    "InvalidGoalError",
    "InvalidStartError",
    "InvalidTrajectoryError",
    "LimitExceededError",
    "MissingExtraError",
    "ModelFileError",
    "NonFiniteError",
    "ObjectiveFileError",
    "RobotFileError",
    "RobotWarning",
    "SceneFileError",
    "SettingsError",
    "ShapeError",
    "ShardsFailedError",
    "TaskFileError",
    "UnknownNameError",
]


class GenplanError(ValueError):
    """An argument genplan cannot use; the message names the argument and the problem."""


class ShapeError(GenplanError):
    """An array or vector of the wrong shape or length (or not readable as numbers)."""


class NonFiniteError(GenplanError):
    """A NaN or infinity where a finite number is needed; the message gives the first one."""


class UnknownNameError(GenplanError):
    """A name (robot, link, joint, frame, term, sampler, environment, ...) that is not known;
    the message lists the known ones."""


class SettingsError(GenplanError):
    """A setting with a bad value, of the wrong type, or not known; the message names the field."""


class RobotFileError(GenplanError):
    """A robot description (URDF, SRDF, mesh) that exists but cannot be read into a model."""


class RobotWarning(UserWarning):
    """A robot that loads but may not be what its files mean: an SRDF group state genplan does
    not use that names joints the URDF lacks, or self-collision pairs in contact at the default
    configuration (or in every sampled one) that no ``<disable_collisions>`` covers. The message
    names the file, the names or pairs, and the remedy (docs/ROBOTS.md). Not an error: the one
    class in this module that is no :class:`GenplanError`."""


class TaskFileError(GenplanError):
    """A task description (task file or its data) that cannot be read: bad TOML, an unknown term
    kind or key, a value of the wrong form."""


class SceneFileError(GenplanError):
    """A scene (scene file or its data, docs/SCENES.md) that cannot be used: bad TOML, an unknown
    key or shape table, a missing field, a value of the wrong length, not finite or not positive,
    a missing mesh file, a duplicate obstacle name; the message names the file (or scene), the
    table and the field."""


class ObjectiveFileError(GenplanError):
    """An objective (objective file or its data, :mod:`genplan.seq2seq.objectives`) that cannot be
    used: bad TOML, an unknown term kind or key, a value of the wrong form, a python term without
    the opt-in; the message names the file, the term and the key."""


class DataFileError(GenplanError):
    """A file of arrays (``.npz``: a trajectory, an input, targets, a recording) that exists but
    cannot be read: not a zip file, a member failing its checksum (a flipped bit), truncated, an
    array that is not one; the message names the file and the reason."""


class ModelFileError(GenplanError):
    """A trained model (safetensors weights + JSON card) that is corrupt, tampered with, made for
    another robot, or otherwise cannot be vouched for."""


class InvalidStartError(GenplanError):
    """A planning start that the result's guarantee cannot rest on (e.g. in collision)."""


class InvalidGoalError(GenplanError):
    """Planning goals that the result's guarantee cannot rest on (e.g. none of them valid)."""


class InvalidTrajectoryError(GenplanError):
    """A path that cannot be timed (a state outside the joint limits, no parameterisation within
    the velocity and acceleration limits) or a trajectory that fails its own check (a sample
    outside the joint limits, in collision, or off the task's manifold); the message names the
    first bad state or sample (index, time) and the limit, pair or term it breaks."""


class CallbackError(GenplanError):
    """A Python sampler, projector or checker called back from the native core returned a value
    of the wrong shape or type."""


class LimitExceededError(GenplanError):
    """A trajectory whose execution exceeds the robot's rated joint limits (torque or speed),
    refused under strict checking (``genplan.control.execute(..., strict=True)``); the message
    names the joint, the time, the value and the limit."""


class MissingExtraError(GenplanError):
    """An optional part of genplan that needs a package not installed (e.g. Ray for ``--ray``, a peer of a benchmark);
    the message says what to install."""


class ShardsFailedError(GenplanError):
    """A run whose shards did not all finish: ``failures`` maps each failed shard's index to why
    (its last error, and how many attempts were made)."""

    def __init__(self, message: str, failures: dict[int, str]) -> None:
        super().__init__(message)
        self.failures = failures
