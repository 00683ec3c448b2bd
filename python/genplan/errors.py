"""The errors genplan raises for a caller's bad input, one class per kind of problem.

Every class is a subclass of :class:`GenplanError`, itself a subclass of :class:`ValueError`, so
``except ValueError`` keeps working while tests and callers can match the kind by type::

    from genplan.errors import UnknownNameError
    try:
        robot.link_poses(q, ["no_such_link"])
    except UnknownNameError as exc:
        print(exc)          # unknown link 'no_such_link' (known: ...)

The classes the native core raises are defined once, in ``genplan._core`` (the table in
rust/python/src/errors.rs, whose classes say ``genplan.errors`` as their module), and re-exported
here: ``genplan.errors.ShapeError is genplan._core.ShapeError``, so an error has one type
whichever layer found it. The errors only Python raises are defined below, as subclasses of them.
A file that does not exist raises the standard :class:`FileNotFoundError`; a file that exists but
cannot be used raises :class:`RobotFileError`, :class:`TaskFileError`, :class:`SceneFileError`,
:class:`ModelFileError` or :class:`DataFileError`. See docs/ARCHITECTURE.md ("Errors").
"""

from __future__ import annotations

from genplan._core import (
    CallbackError,
    GenplanError,
    InvalidGoalError,
    InvalidStartError,
    InvalidTrajectoryError,
    LimitExceededError,
    NonFiniteError,
    RobotFileError,
    SettingsError,
    ShapeError,
    UnknownNameError,
)

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


class MissingExtraError(GenplanError):
    """An optional part of genplan that needs a package not installed (e.g. Ray for ``--ray``, a peer of a benchmark);
    the message says what to install."""


class ShardsFailedError(GenplanError):
    """A run whose shards did not all finish: ``failures`` maps each failed shard's index to why
    (its last error, and how many attempts were made)."""

    def __init__(self, message: str, failures: dict[int, str]) -> None:
        super().__init__(message)
        self.failures = failures

    def __reduce__(self) -> tuple[type[ShardsFailedError], tuple[str, dict[int, str]], dict[str, object]]:
        # pickled with both arguments (the default passes ``args``, the message alone, which
        # __init__ refuses), so that the error crosses a process boundary intact; the instance's
        # other attributes (notes) as the default keeps them
        return (type(self), (str(self), self.failures), dict(vars(self)))
