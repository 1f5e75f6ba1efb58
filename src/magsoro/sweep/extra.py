"""The packages of the ``sweep`` extra (dask.distributed, pyarrow): the core install leaves them out, and the code
that needs them imports them through here, so a missing one ends in one line naming the extra."""

from magsoro.sweep.params import SweepError

#: how to install the extra, as the messages say it
INSTALL = "pip install 'magsoro[sweep]'"


def missing_extra_message(what: str, module: str) -> str:
    """The one line: what needs the extra, the module missing, and the install command."""
    return f"{what} needs the sweep extra ({module} is not installed): {INSTALL}"


#: what needs dask.distributed, in the message
CLUSTER = "a sweep on a Dask cluster (a LocalCluster, or --scheduler; --workers 0 runs in this process without it)"


def require_distributed(what: str = CLUSTER):
    """The ``distributed`` module; :class:`SweepError` with one line naming the extra when it is missing."""
    try:
        import distributed
    except ImportError:
        raise SweepError(missing_extra_message(what, "dask.distributed")) from None
    return distributed


def parquet_note() -> str | None:
    """One line when pyarrow is missing (summary.parquet is then not written; summary.csv is), else None."""
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return missing_extra_message("summary.parquet", "pyarrow") + "; summary.csv is written without it"
    return None
