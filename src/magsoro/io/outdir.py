"""The output folder of a run, and what a reader can tell from its run.json.

A run writes into a folder that is new, empty, or holds a previous magsoro run; a previous run is replaced only
when asked (``--overwrite``), and then nothing of it remains, so old frames or an old report never sit beside new
results. A folder with anything else in it is refused, with or without ``--overwrite``.

run.json carries the process id, the host and a heartbeat time (rewritten at every record and at least every
:data:`HEARTBEAT_S` seconds of wall time while the run steps): :func:`run_state` tells a run that is still going
from one that was killed (SIGKILL, power cut) and left run.json saying "running".
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import time
from pathlib import Path

from magsoro.errors import OutputError, output_error

HEARTBEAT_S = 10.0  # wall seconds between heartbeats of a stepping run
STALE_AFTER_S = 120.0  # a "running" run.json from another host whose heartbeat is older than this is stale


def read_run_info(directory) -> dict | None:
    """The run.json of ``directory`` as a dict, or None when there is none or it is not a magsoro run.json."""
    path = Path(directory) / "run.json"
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) and "magsoro_version" in info and "status" in info else None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    except (OSError, OverflowError, ValueError):
        return False
    return True


def run_state(info: dict, now: float | None = None) -> tuple[str, str]:
    """(state, why) of a run from its run.json: the recorded status, except that a run.json saying "running"
    whose process is gone is "stale". On the host that wrote it the process id decides; elsewhere a heartbeat
    older than :data:`STALE_AFTER_S` does."""
    status = str(info.get("status", "unknown"))
    if status != "running":
        return status, ""
    now = time.time() if now is None else now
    beat = info.get("heartbeat_unix")
    age = now - beat if isinstance(beat, (int, float)) else None
    age_txt = f"last heartbeat {age:.0f} s ago" if age is not None else "no heartbeat recorded"
    pid, host = info.get("pid"), info.get("machine")
    if isinstance(pid, int) and host == platform.node():
        if not _pid_alive(pid):
            return "stale", f"run.json says 'running' but its process {pid} on {host} is gone ({age_txt})"
        return "running", f"process {pid} on {host} is alive ({age_txt})"
    if age is None or age > STALE_AFTER_S:
        return "stale", f"run.json says 'running' but {age_txt} (limit {STALE_AFTER_S:.0f} s; written on {host})"
    return "running", age_txt


def prepare_output_dir(path, overwrite: bool = False, flag: str = "--out") -> Path:
    """Make ``path`` ready for a new run and return it: created when missing; an empty folder is used as is; a
    folder holding a previous magsoro run is emptied when ``overwrite`` is set and refused otherwise; anything
    else (a file, a folder with other files, a run still going) is refused with one line naming the path."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{flag}: {out} is a file, not a folder; name a new or empty folder")
    if out.is_dir():
        try:
            entries = list(out.iterdir())
        except OSError as exc:
            raise output_error(out, exc) from None
        if entries:
            info = read_run_info(out)
            if info is None:
                raise OutputError(f"{flag}: {out} is not empty and holds no magsoro run (no run.json of ours); "
                                  f"name a new or empty folder")
            state, why = run_state(info)
            if state == "running":
                raise OutputError(f"{flag}: {out} holds a run that is still going ({why}); name another folder")
            if not overwrite:
                raise OutputError(f"{flag}: {out} holds a previous run (status '{state}'); add --overwrite to "
                                  f"replace it, or name a new folder")
            try:
                for entry in entries:
                    if entry.is_dir() and not entry.is_symlink():
                        shutil.rmtree(entry)
                    else:
                        entry.unlink()
            except OSError as exc:
                raise output_error(out, exc) from None
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(out, exc) from None
    return out
