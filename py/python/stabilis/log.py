"""Measurement logs as numpy arrays.

An MCAP log (JSON messages with ``t`` in seconds, as written by ``stabilis sim``) or a CSV file
(a header row with a ``t`` column) becomes ``{topic: (t, {field: values})}``.

>>> import stabilis
>>> run = stabilis.sim.run("wheel-pendulum", duration=1.0)
>>> t, fields = run["/wheel_pendulum/state"]
>>> len(t) == len(fields["phi"]) == 201
True
"""
from . import _stabilis

_native = _stabilis.log


class Log(dict):
    """``{topic: (t, {field: values})}`` with the log's metadata records.

    Attributes:
        metadata: ``{record name: {key: value}}`` (e.g. ``metadata["experiment"]``).
        complete: False when the file stops early (a run that was cut off); what was read is
            still returned.
        problem: why reading stopped early, or None.
    """

    def __init__(self, topics, metadata, complete=True, problem=None):
        super().__init__(topics)
        self.metadata = metadata
        self.complete = complete
        self.problem = problem

    @property
    def experiment(self):
        """The ``experiment`` metadata record ({} if the log has none)."""
        return self.metadata.get("experiment", {})


def read_mcap(path, topics=None):
    """Reads an MCAP log into a :class:`Log`.

    Raises ``stabilis.LogError`` when the file is missing, is not MCAP, holds a message that is
    not a JSON object of finite numbers, or lacks one of ``topics``.
    """
    topics_, metadata, complete, problem = _native.read_mcap(
        str(path), None if topics is None else list(topics)
    )
    return Log(topics_, metadata, complete, problem)


def read_csv(path):
    """Reads a CSV file with a header row and a ``t`` column: returns ``(t, {field: values})``."""
    return _native.read_csv(str(path))


__all__ = ["Log", "read_mcap", "read_csv"]
