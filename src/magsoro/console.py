"""What the command line prints while it works: Warp's start-up output, progress, the closing summary.

- :func:`configure_warp`: Warp's banner ("Warp 1.x initialized: ..."), its per-module "Module ... load on device
  ... took ... ms" lines and, on a machine without a CUDA driver, its native "CUDA warning" are hidden unless the
  user asks for them (``-v``).
- :class:`Progress`: on a terminal one status line redrawn in place; into a file or a pipe one plain line every
  few seconds (no carriage returns, so logs stay readable).
- :func:`settled`: whether a dynamic run came to rest, from the kinetic energy the run command samples at each
  record (:class:`SettleWatch`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time

#: seconds between two progress lines when stderr is not a terminal
LINE_EVERY_S = 5.0
#: seconds between two redraws of the status line on a terminal
REDRAW_EVERY_S = 0.2

#: a run has settled when the free particles' kinetic energy at each of the last SETTLE_RECORDS records is below
#: SETTLE_ENERGY times the largest kinetic energy recorded in the run (the top particle speed then about a
#: hundredth of its largest), or when the fastest free particle would move less than SETTLE_CELLS cells over one
#: record interval (a run in which nothing moves)
SETTLE_RECORDS = 2
SETTLE_ENERGY = 1e-4
SETTLE_CELLS = 1e-3


def configure_warp(verbose: bool = False) -> None:
    """Before Warp starts: without ``verbose`` its banner and module-load lines are switched off and its native
    no-driver warning (written to the process's stderr while Warp initialises) is dropped; with ``verbose`` Warp
    prints as it does by default. Calling it again, or after Warp has started, changes only the log level."""
    import warp as wp

    if verbose:
        if hasattr(wp, "LOG_INFO") and hasattr(wp.config, "log_level"):
            wp.config.log_level = wp.LOG_INFO
        wp.config.quiet = False
        wp.init()
        return
    from magsoro.warp_setup import quiet_warp

    quiet_warp()
    with _stderr_silenced():
        wp.init()


@contextlib.contextmanager
def _stderr_silenced():
    """File descriptor 2 points to the null device while the block runs (native code writes there directly)."""
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # a replaced sys.stderr without a descriptor
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


def is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def clock(seconds: float) -> str:
    """Wall time as '4.2 s', '3 min 48 s' or '1 h 02 min'."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    if seconds < 3600:
        return f"{int(seconds // 60)} min {int(seconds % 60):02d} s"
    return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60):02d} min"


class Progress:
    """A status line on ``stream`` (stderr). ``update(text)`` may be called as often as wanted: on a terminal the
    line is redrawn in place at most every REDRAW_EVERY_S; otherwise a plain line is written at most every
    ``every`` seconds (and the first at once). ``close()`` ends a redrawn line. Disabled: does nothing."""

    def __init__(self, stream=None, enabled: bool = True, every: float = LINE_EVERY_S):
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.tty = is_terminal(self.stream)
        self.every = REDRAW_EVERY_S if self.tty else every
        self.last = None  # monotonic time of the last write
        self.width = 0  # the redrawn line's length, to blank what a shorter one leaves

    def update(self, text: str, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and self.last is not None and now - self.last < self.every:
            return
        self.last = now
        if self.tty:
            self.stream.write("\r" + text.ljust(self.width))
            self.width = len(text)
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def line(self, text: str, stream=None) -> None:
        """A line that stays (a level solved): ends the redrawn line first."""
        self.close()
        print(text, file=stream or self.stream, flush=True)

    def close(self) -> None:
        if self.enabled and self.tty and self.width:
            self.stream.write("\r" + " " * self.width + "\r")
            self.stream.flush()
            self.width = 0


class SettleWatch:
    """The free particles' kinetic energy and top speed at each record of a dynamic run (a host read-back of the
    velocities, once per record), for :meth:`verdict`."""

    def __init__(self):
        self.energies: list[float] = []
        self.speeds: list[float] = []
        self.times: list[float] = []

    def sample(self, sim) -> None:
        energy, speed = sim.kinetic_energy()
        self.energies.append(energy)
        self.speeds.append(speed)
        self.times.append(sim.time)

    def verdict(self, dx: float) -> tuple[bool | None, str]:
        """(settled, the criterion and the numbers that decided it); settled None with fewer than
        SETTLE_RECORDS records after the start."""
        n = SETTLE_RECORDS
        if len(self.energies) < n:
            return None, (f"fewer than {n} records to judge from (settling: kinetic energy below {SETTLE_ENERGY:g} of "
                          f"its peak at the last {n} records)")
        peak = max(self.energies)
        last = self.energies[-n:]
        interval = self.times[-1] - self.times[-2]
        drift = max(self.speeds[-n:]) * interval / dx  # cells the fastest particle would cross per record interval
        ratio = max(last) / peak if peak > 0 else 0.0
        ok = ratio <= SETTLE_ENERGY or drift <= SETTLE_CELLS
        why = (f"kinetic energy at the last {n} records up to {ratio:.1e} of its peak, top particle speed "
               f"{self.speeds[-1]:.3g} m/s; settled means below {SETTLE_ENERGY:g} of the peak, or under "
               f"{SETTLE_CELLS:g} cell per record interval")
        return ok, why


def probe_unit(column: str, probes: list) -> str:
    """The unit of a metrics column: field probes T, collider_force probes N, the others m."""
    for p in sorted(probes, key=lambda p: len(p.name), reverse=True):
        if column == p.name or column.startswith(p.name + "_"):
            return {"field": "T", "collider_force": "N"}.get(getattr(p, "kind", ""), "m")
    return ""


def probe_lines(values: dict, probes: list, indent: str = "  ") -> list[str]:
    """One line per probe: 'tip: x 0.01208 m, y 0.01317 m' (columns grouped by probe, in order)."""
    groups: dict[str, list[str]] = {}
    names = sorted((p.name for p in probes), key=len, reverse=True)
    for col, v in values.items():
        owner = next((n for n in names if col == n or col.startswith(n + "_")), col)
        part = col[len(owner) + 1:] if col != owner else ""
        unit = probe_unit(col, probes)
        groups.setdefault(owner, []).append(f"{part + ' ' if part else ''}{v:.6g}{' ' + unit if unit else ''}")
    return [f"{indent}{name}: {', '.join(parts)}" for name, parts in groups.items()]
