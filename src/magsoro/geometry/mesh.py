"""Closed triangle meshes (STL, OBJ, PLY) as solid shapes for the lattice fill.

trimesh reads the file; membership of lattice points is decided here by casting rays along +z and summing the
signed crossings (the winding number along the ray), so no optional native dependency (rtree, embree) is needed.
Points sharing an (x, y) column share one ray, which makes the lattice fill cost (columns x faces) rather than
(points x faces).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from magsoro.geometry.primitives import Shape

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off", ".glb", ".gltf")


class MeshError(ValueError):
    """A mesh file is missing, unreadable, or not a closed surface that can be repaired."""


def load_mesh(path, scale: float = 1.0, position=(0.0, 0.0, 0.0), rotation=None):
    """Read a mesh file and place it: world = R (scale * file coordinates) + position (m).

    ``scale`` converts file units to metres (1e-3 for a CAD file in mm). A mesh that is not watertight is
    repaired (merged vertices, filled holes, consistent normals) when trimesh can; otherwise MeshError names the
    file. Returns the trimesh.Trimesh in metres with outward normals.
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise MeshError(f"mesh file '{path}' not found")
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise MeshError(f"mesh file '{path}': unsupported format '{path.suffix}'; use {', '.join(MESH_SUFFIXES)}")
    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except ImportError:  # trimesh reaches for an optional text-encoding detector when the bytes are not text
        raise MeshError(f"mesh file '{path}' could not be read: not a valid {path.suffix.lower()} file "
                        f"(neither its text nor its binary form)") from None
    except Exception as exc:  # trimesh raises many kinds on malformed files
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise MeshError(f"mesh file '{path}' could not be read as {path.suffix.lower()}: {reason}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"mesh file '{path}' holds no triangles")
    if not mesh.is_watertight:
        mesh.merge_vertices()
        mesh.update_faces(mesh.nondegenerate_faces())
        mesh.update_faces(mesh.unique_faces())
        trimesh.repair.fill_holes(mesh)
        trimesh.repair.fix_normals(mesh)
        if not mesh.is_watertight:
            raise MeshError(
                f"mesh file '{path}' is not a closed surface and could not be repaired "
                f"({len(trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1))} open edges after repair); close it in the CAD tool"
            )
    if mesh.volume < 0:
        mesh.invert()  # inside-out file: the ray test expects outward normals
    if not scale > 0:
        raise MeshError(f"mesh scale must be > 0, got {scale}")
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64).reshape(3, 3)
    T = np.eye(4)
    T[:3, :3] = scale * R
    T[:3, 3] = np.asarray(position, dtype=np.float64).reshape(3)
    mesh.apply_transform(T)
    return mesh


class MeshShape(Shape):
    """Solid bounded by a closed triangle mesh; vertices (V, 3) and faces (F, 3) in metres, outward normals."""

    dim = 3

    def __init__(self, vertices, faces, name: str = "mesh"):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        self.name = name
        tri = self.vertices[self.faces]
        self._tri = tri
        # signed volume by the divergence theorem: exact for the polyhedron
        self._volume = float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)
        if not self._volume > 0:
            raise MeshError(f"mesh '{name}' encloses no positive volume")

    @classmethod
    def from_file(cls, path, scale: float = 1.0, position=(0.0, 0.0, 0.0), rotation=None) -> "MeshShape":
        mesh = load_mesh(path, scale, position, rotation)
        return cls(mesh.vertices, mesh.faces, name=str(path))

    def bounds(self):
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def volume(self):
        """Volume enclosed by the mesh, m^3 (exact for the polyhedron)."""
        return self._volume

    def contains(self, points):
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros(len(p), dtype=bool)
        lo, hi = self.bounds()
        box = np.all((p >= lo) & (p <= hi), axis=1)
        if not box.any():
            return out
        q = p[box]
        # A fixed, tiny, irrational-ish offset of every ray keeps rays off mesh edges and vertices, which a
        # grid-aligned lattice would otherwise hit exactly on meshes with "round" coordinates (double counting).
        span = float(np.max(hi - lo))
        shift = span * np.array([1.2345678e-9, 2.7182818e-9])
        cols, inverse = np.unique(q[:, :2], axis=0, return_inverse=True)
        inverse = inverse.ravel()
        hit_col, hit_z, hit_sign = self._ray_hits(cols + shift)
        if len(hit_col) == 0:
            return out
        # count signed crossings above each point: sort hits by (column, z) and search
        zlo, zhi = lo[2], hi[2]
        zn = lambda z: 0.25 + 0.5 * (z - zlo) / max(zhi - zlo, 1e-300)  # noqa: E731  maps z into (0, 1)
        keys = hit_col + zn(hit_z)
        order = np.argsort(keys, kind="stable")
        keys, signs = keys[order], hit_sign[order]
        csum = np.concatenate([[0], np.cumsum(signs)])
        below = np.searchsorted(keys, inverse + zn(q[:, 2]), side="right")
        col_end = np.searchsorted(keys, inverse + 1.0, side="left")
        winding = csum[col_end] - csum[below]
        out[np.flatnonzero(box)] = winding != 0
        return out

    def _ray_hits(self, cols):
        """Crossings of vertical rays through ``cols`` (M, 2) with the faces: column index, z, sign of n_z."""
        tri = self._tri
        v0 = tri[:, 0]
        d = tri[:, 1, :2] - v0[:, :2]
        e = tri[:, 2, :2] - v0[:, :2]
        den = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]
        keep = np.abs(den) > 1e-30 * np.max(np.abs(tri)) ** 2  # faces seen edge-on carry no crossing
        tri, v0, d, e, den = tri[keep], v0[keep], d[keep], e[keep], den[keep]
        sign = np.sign(den)  # z component of the face normal (v1 - v0) x (v2 - v0)
        fmin, fmax = tri[:, :, :2].min(axis=1), tri[:, :, :2].max(axis=1)
        dz1, dz2 = tri[:, 1, 2] - v0[:, 2], tri[:, 2, 2] - v0[:, 2]
        out_c, out_z, out_s = [], [], []
        chunk = max(1, int(4e6 // max(len(tri), 1)))
        for s in range(0, len(cols), chunk):
            c = cols[s : s + chunk]
            near = (c[:, None, 0] >= fmin[None, :, 0]) & (c[:, None, 0] <= fmax[None, :, 0]) & (c[:, None, 1] >= fmin[None, :, 1]) & (c[:, None, 1] <= fmax[None, :, 1])
            ci, fi = np.nonzero(near)
            if len(ci) == 0:
                continue
            w = c[ci] - v0[fi, :2]
            u = (w[:, 0] * e[fi, 1] - w[:, 1] * e[fi, 0]) / den[fi]
            v = (d[fi, 0] * w[:, 1] - d[fi, 1] * w[:, 0]) / den[fi]
            inside = (u >= 0) & (v >= 0) & (u + v <= 1)
            ci, fi, u, v = ci[inside], fi[inside], u[inside], v[inside]
            out_c.append(ci + s)
            out_z.append(v0[fi, 2] + u * dz1[fi] + v * dz2[fi])
            out_s.append(sign[fi])
        if not out_c:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        return np.concatenate(out_c).astype(np.float64), np.concatenate(out_z), np.concatenate(out_s)
