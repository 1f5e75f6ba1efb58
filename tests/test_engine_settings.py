"""The engine's closed categories are named once (magsoro.mpm.settings): the kernels' int codes come from the enums,
a collider's row is laid out as ColliderRow says, and the kernel sources compare names, not numbers."""

import re
from pathlib import Path

import numpy as np

from magsoro.fields.profiles import Keyframes
from magsoro.mpm import colliders, contact, g2p, grid, p2g, stencil
from magsoro.mpm.colliders import Collider
from magsoro.mpm.settings import (COLLIDER_MODES, COLLIDER_STRIDE, ColliderKind, ColliderMode, ColliderRow, FUpdate,
                                  MagnetizationFollows, NodeClass, P2GFlag)

MPM = Path(__file__).resolve().parents[1] / "src" / "magsoro" / "mpm"


def test_kernel_codes_come_from_the_enums():
    assert (p2g.P2G_TOTAL, p2g.P2G_APART) == (P2GFlag.TOTAL, P2GFlag.APART)
    assert (g2p.F_FROM_GRID, g2p.F_FROM_REMAP, g2p.F_TOTAL, g2p.F_REMAP_APART) == tuple(FUpdate)
    assert (contact.SINGLE, contact.BODIES, contact.FOLD) == tuple(NodeClass)
    assert (grid.STICKY, grid.FRICTION, grid.SYMMETRY) == (ColliderMode.STICKY, ColliderMode.FRICTION, ColliderMode.SYMMETRY)
    assert (colliders.HALF_SPACE, colliders.BOX, colliders.SPHERE, colliders.CYLINDER) == tuple(ColliderKind)
    assert colliders.MODES == COLLIDER_MODES == {"sticky": 0, "slip": 1, "friction": 2, "symmetry": 3}
    assert stencil.MAGNETIZATION_FOLLOWS == {m.name: int(m) for m in MagnetizationFollows}
    assert colliders.COLLIDER_STRIDE == COLLIDER_STRIDE


def test_collider_row_layout():
    path = Keyframes([0.0, 2.0], [[0.0, 0.0, 0.0], [2.0, 4.0, 6.0]])
    c = Collider.cylinder([0.0, 0.0, 0.0], 0.5, 1.5, axis=(1, 0, 0), mode="friction", friction=0.3, path=path)
    r = c.row(1.0)
    assert r.shape == (COLLIDER_STRIDE,)
    assert r[ColliderRow.KIND] == ColliderKind.CYLINDER and r[ColliderRow.MODE] == ColliderMode.FRICTION
    assert r[ColliderRow.FRICTION] == 0.3
    np.testing.assert_array_equal(r[ColliderRow.POSITION : ColliderRow.POSITION + 3], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(r[ColliderRow.VELOCITY : ColliderRow.VELOCITY + 3], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(r[ColliderRow.ROTATION : ColliderRow.ROTATION + 9], c.rotation.ravel())
    np.testing.assert_array_equal(r[ColliderRow.SIZE : ColliderRow.SIZE + 3], [0.5, 1.5, 0.0])
    assert ColliderMode.named("symmetry") is ColliderMode.SYMMETRY


def test_kernel_sources_compare_names_not_numbers():
    bare = re.compile(r"\b(mode|kind|follows|s|split\[idx\]) *[!=]= *\d|flags *(%|//)")
    found = []
    for name in ("colliders.py", "grid.py", "p2g.py", "g2p.py", "contact.py", "stencil.py"):
        for i, line in enumerate((MPM / name).read_text().splitlines(), 1):
            if bare.search(line.split("#")[0]):
                found.append(f"{name}:{i}: {line.strip()}")
    assert not found, "bare integer codes (name them in magsoro.mpm.settings):\n" + "\n".join(found)
