"""Warp start-up settings shared by the command line and the sweep workers."""

from __future__ import annotations


def quiet_warp() -> None:
    """Keep Warp's banner and per-module load lines off stdout (JSON output, worker logs).

    'quiet' is the historical switch; Warp >= 1.10 reads log_level instead, so both are set."""
    import warp as wp

    wp.config.quiet = True
    if hasattr(wp, "LOG_WARNING") and hasattr(wp.config, "log_level"):
        wp.config.log_level = wp.LOG_WARNING
