"""Generate the meshes used by scenes/*.toml (our own geometry, no third-party CAD files).

    python scripts/make_meshes.py            # writes scenes/meshes/gripper_six_arm.stl

gripper_six_arm.stl: the six-arm gripper of Xu et al. (seed 000 sec 4.5) as a flat star, in millimetres (the
scene loads it with scale = 1e-3). Seed 000 gives no dimensions; ours (scenes/gripper.toml says why): six arms
1.5 mm wide reaching 9 mm from the centre, 1.5 mm thick, joined by a small hexagonal hub (an arm's edges meet
the hub 1.5 mm from the centre).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

ARMS = 6
ARM_WIDTH_MM = 1.5
ARM_REACH_MM = 9.0  # centre to arm tip
HUB_MM = 1.5  # centre to where an arm's edges meet the hub (> 0.75 / tan 30 deg = 1.3 keeps the outline simple)
THICKNESS_MM = 1.5


def star_outline(arms=ARMS, width=ARM_WIDTH_MM, reach=ARM_REACH_MM, hub=HUB_MM) -> np.ndarray:
    """Counter-clockwise outline (K, 2) in mm: for each arm its base and tip corners."""
    pts = []
    for k in range(arms):
        t = 2 * np.pi * k / arms
        along, side = np.array([np.cos(t), np.sin(t)]), np.array([-np.sin(t), np.cos(t)])
        half = 0.5 * width * side
        pts += [hub * along - half, reach * along - half, reach * along + half, hub * along + half]
    return np.array(pts)


def extrude_star_shaped(outline: np.ndarray, thickness: float):
    """Closed triangle mesh of a polygon that is star-shaped about the origin, extruded over z in
    [-thickness/2, thickness/2]: fan triangles on the caps, two triangles per side. Outward normals."""
    K = len(outline)
    h = 0.5 * thickness
    verts = np.concatenate([[[0.0, 0.0, -h]], np.c_[outline, np.full(K, -h)],
                            [[0.0, 0.0, h]], np.c_[outline, np.full(K, h)]])
    bc, b0, tc, t0 = 0, 1, K + 1, K + 2
    faces = []
    for i in range(K):
        j = (i + 1) % K
        faces.append([bc, b0 + j, b0 + i])  # bottom cap, normal -z
        faces.append([tc, t0 + i, t0 + j])  # top cap, normal +z
        faces.append([b0 + i, b0 + j, t0 + j])  # side, outward for a counter-clockwise outline
        faces.append([b0 + i, t0 + j, t0 + i])
    return verts, np.array(faces)


def main(out_dir=None) -> list[Path]:
    import trimesh

    out_dir = Path(out_dir) if out_dir else Path(__file__).resolve().parents[1] / "scenes" / "meshes"
    out_dir.mkdir(parents=True, exist_ok=True)
    v, f = extrude_star_shaped(star_outline(), THICKNESS_MM)
    mesh = trimesh.Trimesh(v, f, process=True)
    assert mesh.is_watertight and mesh.volume > 0, "generated gripper mesh must be closed with outward normals"
    path = out_dir / "gripper_six_arm.stl"
    path.write_bytes(trimesh.exchange.stl.export_stl_ascii(mesh).encode())
    print(f"{path}: {len(mesh.faces)} faces, volume {mesh.volume:.4f} mm^3")
    return [path]


if __name__ == "__main__":
    main()
