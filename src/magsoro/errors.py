"""Exceptions raised by magsoro. Each carries a message meant to be shown to the user as is."""


class MagsoroError(Exception):
    """Base class of every error magsoro raises on purpose."""


class SceneError(MagsoroError):
    """A scene (file or in-code description) is invalid; the message names the key and what is allowed."""


class SimulationError(MagsoroError):
    """A run could not go on (non-finite state, inverted element, ...); the message names step, time and cause."""

    def __init__(self, message: str, step: int | None = None, time: float | None = None, input_rejected: bool = False):
        super().__init__(message)
        self.step = step
        self.time = time
        self.input_rejected = input_rejected  # the step's input state failed a check (not the state it computed)


class OutputError(MagsoroError):
    """A result could not be written (disk full, read-only folder, a file where a folder is wanted); the message
    names the file and the operating system's reason."""


def output_error(path, exc: OSError) -> OutputError:
    """The one-line OutputError for an OSError met while writing ``path``."""
    reason = exc.strerror or type(exc).__name__
    return OutputError(f"cannot write {path}: {reason}" + (f" (errno {exc.errno})" if exc.errno else ""))


class Terminated(KeyboardInterrupt):
    """The process was asked to stop by a signal (SIGTERM: what ``timeout``, Slurm and ``docker stop`` send).
    A KeyboardInterrupt, so every place that ends a run cleanly on Ctrl-C does the same for it."""

    def __init__(self, signum: int):
        import signal

        self.signum = int(signum)
        self.signame = signal.Signals(signum).name
        super().__init__(f"terminated by {self.signame}")
