"""The output folder of a run, and what a reader can tell from its run.json.

A run writes into a folder that is new, empty, or holds a previous magsoro run; a previous run is replaced only
when asked (``--overwrite``), and then nothing of it remains, so old frames or an old report never sit beside new
results. ``--overwrite`` removes only the files magsoro writes there (run.json's ``files``, names and patterns out of
:data:`RUN_FILES`); a folder holding anything else (a scene file, notes, a data folder) is refused naming it, and a
folder without a run.json of ours is refused, with or without ``--overwrite``.

run.json carries the process id, the host and a heartbeat time (rewritten at every record and at least every
:data:`HEARTBEAT_S` seconds of wall time while the run steps or solves): :func:`run_state` tells a run that is still
going from one that was killed (SIGKILL, power cut) and left run.json saying "running", including one whose process
id has since been given to another process (containers restart with the same small ids).
"""

from __future__ import annotations

import fnmatch
import json
import os
import platform
import time
from pathlib import Path

from magsoro.errors import OutputError, output_error

HEARTBEAT_S = 10.0  # wall seconds between heartbeats of a stepping run
STALE_AFTER_S = 120.0  # a "running" run.json from another host whose heartbeat is older than this is stale
#: a "running" run.json of this host whose process id is alive but whose heartbeat is older than this is stale: the
#: id now belongs to another process. A run beats every HEARTBEAT_S while it steps and while a static solve works
#: (magsoro.io.recorder.RunWriter.beating), so 10 minutes is many missed beats, not a slow step.
STALE_ALIVE_AFTER_S = 600.0

#: The files a run writes into its folder, relative to it (fnmatch patterns), listed in run.json's ``files``: what
#: ``--overwrite`` may remove. report.html is the default page of ``magsoro report`` on the folder. Atomic writes
#: leave ``.NAME.*.tmp`` only when killed mid-write; those of these names count as the run's too.
RUN_FILES = ("run.json", "metrics.csv", "particles.pvd", "final.npz", "last_good.npz", "frames/frame_*.vtp",
             "report.html")


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
    if isinstance(pid, int) and not isinstance(pid, bool) and host == platform.node():
        if pid == os.getpid() and (age is None or age > STALE_AFTER_S):
            # the id is ours (a container restarted), and no run of ours has beaten since: its writer is gone
            return "stale", f"run.json says 'running' but its process id {pid} is now this process's ({age_txt})"
        if not _pid_alive(pid):
            return "stale", f"run.json says 'running' but its process {pid} on {host} is gone ({age_txt})"
        if age is not None and age > STALE_ALIVE_AFTER_S:
            return "stale", (f"run.json says 'running' and a process {pid} exists on {host}, but the {age_txt} "
                             f"(limit {STALE_ALIVE_AFTER_S:.0f} s; a run beats every {HEARTBEAT_S:.0f} s): the id "
                             f"belongs to another process now")
        return "running", f"process {pid} on {host} is alive ({age_txt})"
    if age is None or age > STALE_AFTER_S:
        return "stale", f"run.json says 'running' but {age_txt} (limit {STALE_AFTER_S:.0f} s; written on {host})"
    return "running", age_txt


def run_file_patterns(info: dict) -> list[str]:
    """The patterns of the files the run of ``info`` wrote: run.json's ``files`` as far as they are among
    :data:`RUN_FILES` (a run.json is only a file: it cannot widen what --overwrite removes), all of RUN_FILES for a
    run.json written before the list existed."""
    listed = info.get("files")
    if not isinstance(listed, list):
        return list(RUN_FILES)
    return [p for p in listed if p in RUN_FILES]


def _is_run_file(rel: str, patterns: list[str]) -> bool:
    """Whether ``rel`` (a path relative to the run folder, '/'-separated) is one of the run's files, or the temp
    file an interrupted atomic write of one left (``.NAME.XXXX.tmp`` beside it)."""
    folder, _, name = rel.rpartition("/")
    if name.startswith(".") and name.endswith(".tmp"):
        target = name[1:-4].rsplit(".", 1)[0]
        rel = f"{folder}/{target}" if folder else target
    return any(fnmatch.fnmatchcase(rel, p) for p in patterns)


def _run_entries(out: Path, patterns: list[str]) -> tuple[list[Path], list[Path], str | None]:
    """(the run's files, its folders, the first entry that is not the run's or None) under ``out``. A folder is
    the run's when patterns reach into it and everything in it is; links are never followed."""
    files, folders = [], []
    folder_names = {p.split("/", 1)[0] for p in patterns if "/" in p}
    for entry in sorted(out.iterdir()):
        if entry.is_dir() and not entry.is_symlink():
            if entry.name not in folder_names:
                return files, folders, entry.name + "/"
            for sub in sorted(entry.iterdir()):
                rel = f"{entry.name}/{sub.name}"
                if sub.is_dir() and not sub.is_symlink():
                    return files, folders, rel + "/"
                if not _is_run_file(rel, patterns):
                    return files, folders, rel
                files.append(sub)
            folders.append(entry)
        elif _is_run_file(entry.name, patterns):
            files.append(entry)
        else:
            return files, folders, entry.name
    return files, folders, None


def prepare_output_dir(path, overwrite: bool = False, flag: str = "--out") -> Path:
    """Make ``path`` ready for a new run and return it: created when missing; an empty folder is used as is; a
    folder holding a previous magsoro run is emptied of that run's files when ``overwrite`` is set and refused
    otherwise; anything else (a file, a folder with other files, a run still going) is refused with one line
    naming the path, and with ``overwrite`` the first entry that is not the run's. Nothing is removed unless
    everything in the folder is the run's."""
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
                files, folders, foreign = _run_entries(out, run_file_patterns(info))
            except OSError as exc:
                raise output_error(out, exc) from None
            if foreign is not None:
                raise OutputError(f"{flag}: {out} holds '{foreign}', which magsoro did not write (not among run.json's "
                                  f"files); --overwrite removes only a run's own files: move it out, or name a new "
                                  f"folder")
            try:
                for f in files:
                    f.unlink()
                for d in folders:
                    d.rmdir()
            except OSError as exc:
                raise output_error(out, exc) from None
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(out, exc) from None
    return out
