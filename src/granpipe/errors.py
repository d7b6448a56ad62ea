"""Exceptions raised by granpipe, each carrying the context a user needs to act."""


class GranpipeError(Exception):
    """Base class of granpipe's own errors."""


class ConfigError(GranpipeError, ValueError):
    """A configuration is invalid; the message names the offending key."""


class RunFileError(GranpipeError, ValueError):
    """A stage's input file is unreadable, or does not belong with the others; the
    message names the file."""


class WriteError(GranpipeError):
    """A stage could not write its output; the message names the file and the operating
    system's reason (e.g. ``No space left on device (ENOSPC)``)."""


class SimulationError(GranpipeError, RuntimeError):
    """A simulation reached a bad state (NaN/inf, or an overlap past the bound).

    Attributes give where it happened so that the replica can be rerun by hand.
    """

    def __init__(self, message, *, particle=None, step=None, time=None, **context):
        self.particle = particle
        self.step = step
        self.time = time
        self.context = dict(context)
        parts = [message]
        where = {"particle": particle, "step": step, "time": time, **context}
        detail = ", ".join(f"{k}={v}" for k, v in where.items() if v is not None)
        if detail:
            parts.append(f"({detail})")
        super().__init__(" ".join(parts))

    def with_context(self, **context):
        """Return a copy with extra context (study, point, replica, seed)."""
        merged = {**self.context, **context}
        base = str(self.args[0]).split(" (")[0]
        return SimulationError(
            base, particle=self.particle, step=self.step, time=self.time, **merged
        )
