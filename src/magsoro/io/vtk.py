"""ParaView particle output: VTK XML PolyData (.vtp, binary base64 inline) and a .pvd time index."""

from __future__ import annotations

import base64
import struct
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from magsoro.io.files import atomic_write_bytes, atomic_write_text

_VTK_TYPES = {np.dtype(np.float32): "Float32", np.dtype(np.float64): "Float64", np.dtype(np.int32): "Int32", np.dtype(np.int64): "Int64", np.dtype(np.uint8): "UInt8"}


def _data_array(name: str, arr: np.ndarray) -> str:
    arr = np.ascontiguousarray(arr)
    if arr.dtype not in _VTK_TYPES:
        arr = arr.astype(np.float64)
    ncomp = 1 if arr.ndim == 1 else int(np.prod(arr.shape[1:]))
    raw = arr.tobytes()
    # VTK binary inline format: base64 of (UInt32 byte count header + data)
    payload = base64.b64encode(struct.pack("<I", len(raw)) + raw).decode("ascii")
    return (
        f'<DataArray type="{_VTK_TYPES[arr.dtype]}" Name={quoteattr(name)} NumberOfComponents="{ncomp}" format="binary">'
        f"{payload}</DataArray>"
    )


def write_vtp(path, points: np.ndarray, point_data: dict[str, np.ndarray]) -> None:
    """Write particles as vertices with per-point arrays. 2D points get z = 0."""
    pts = np.asarray(points, dtype=np.float64)
    n = len(pts)
    if pts.shape[1] == 2:
        pts = np.concatenate([pts, np.zeros((n, 1))], axis=1)
    conn = np.arange(n, dtype=np.int64)
    offs = np.arange(1, n + 1, dtype=np.int64)
    arrays = "".join(_data_array(k, v) for k, v in point_data.items())
    xml = (
        '<?xml version="1.0"?>\n<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt32">\n'
        f'<PolyData><Piece NumberOfPoints="{n}" NumberOfVerts="{n}" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="0">\n'
        f"<PointData>{arrays}</PointData>\n"
        f"<Points>{_data_array('Points', pts)}</Points>\n"
        f"<Verts>{_data_array('connectivity', conn)}{_data_array('offsets', offs)}</Verts>\n"
        "</Piece></PolyData>\n</VTKFile>\n"
    )
    atomic_write_bytes(path, xml.encode("ascii"))


def write_pvd(path, entries: list[tuple[float, str]]) -> None:
    """Time index of .vtp files (paths relative to the .pvd)."""
    rows = "\n".join(f'    <DataSet timestep="{t:.9g}" part="0" file={quoteattr(f)}/>' for t, f in entries)
    atomic_write_text(
        path,
        f'<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n',
    )


def read_vtp(path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Read back a file written by :func:`write_vtp` (points, point data). A file that is missing, cut short or
    not one of ours raises :class:`~magsoro.errors.MagsoroError` naming it."""
    import binascii
    import xml.etree.ElementTree as ET

    from magsoro.errors import MagsoroError

    try:
        return _read_vtp(path)
    except OSError as exc:
        raise MagsoroError(f"{path}: cannot read the particle frame: {exc.strerror or exc}") from None
    except (ET.ParseError, ValueError, KeyError, AttributeError, TypeError, struct.error, binascii.Error) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise MagsoroError(f"{path}: not a readable particle frame ({reason})") from None


def _read_vtp(path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    import xml.etree.ElementTree as ET

    root = ET.parse(Path(path)).getroot()
    inv = {v: k for k, v in _VTK_TYPES.items()}

    def decode(el):
        raw = base64.b64decode(el.text)
        (nbytes,) = struct.unpack("<I", raw[:4])
        if len(raw) - 4 < nbytes:
            raise ValueError(f"array '{el.get('Name')}' cut short: {len(raw) - 4} of {nbytes} bytes")
        arr = np.frombuffer(raw[4 : 4 + nbytes], dtype=inv[el.get("type")])
        nc = int(el.get("NumberOfComponents", "1"))
        return arr.reshape(-1, nc) if nc > 1 else arr

    piece = root.find("PolyData/Piece")
    pts = decode(piece.find("Points/DataArray"))
    data = {el.get("Name"): decode(el) for el in piece.find("PointData")}
    return pts, data
