"""The engine's closed categories are named once (magsoro.mpm.settings): the kernels' int codes come from the enums,
a collider reaches the kernels as a DeviceCollider struct, and the kernel sources compare names, not numbers."""

import re
from pathlib import Path

import numpy as np
import warp as wp

from magsoro.fields.profiles import Keyframes
from magsoro.mpm import colliders
from magsoro.mpm.kernels import contact, g2p, grid, p2g, stencil
from magsoro.mpm.colliders import Collider
from magsoro.mpm.settings import (COLLIDER_MODES, ColliderKind, ColliderMode, FUpdate, MagnetizationFollows, NodeClass,
                                  P2GFlag)

MPM = Path(__file__).resolve().parents[1] / "src" / "magsoro" / "mpm"


def test_kernel_codes_come_from_the_enums():
    assert (p2g.P2G_TOTAL, p2g.P2G_APART) == (P2GFlag.TOTAL, P2GFlag.APART)
    assert (g2p.F_FROM_GRID, g2p.F_FROM_REMAP, g2p.F_TOTAL, g2p.F_REMAP_APART) == tuple(FUpdate)
    assert (contact.SINGLE, contact.BODIES, contact.FOLD) == tuple(NodeClass)
    assert (grid.STICKY, grid.FRICTION, grid.SYMMETRY) == (ColliderMode.STICKY, ColliderMode.FRICTION, ColliderMode.SYMMETRY)
    assert (colliders.HALF_SPACE, colliders.BOX, colliders.SPHERE, colliders.CYLINDER) == tuple(ColliderKind)
    assert colliders.MODES == COLLIDER_MODES == {"sticky": 0, "slip": 1, "friction": 2, "symmetry": 3}
    assert stencil.MAGNETIZATION_FOLLOWS == {m.name: int(m) for m in MagnetizationFollows}


def test_a_collider_reaches_the_kernels_as_a_struct():
    path = Keyframes([0.0, 2.0], [[0.0, 0.0, 0.0], [2.0, 4.0, 6.0]])
    c = Collider.cylinder([0.0, 0.0, 0.0], 0.5, 1.5, axis=(1, 0, 0), mode="friction", friction=0.3, path=path)
    r = c.record(1.0)
    assert r.dtype == colliders.DeviceCollider.numpy_dtype()
    assert r["kind"] == ColliderKind.CYLINDER and r["mode"] == ColliderMode.FRICTION
    assert r["friction"] == 0.3
    np.testing.assert_array_equal(r["position"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(r["velocity"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(r["rotation"], c.rotation)
    np.testing.assert_array_equal(r["size"], [0.5, 1.5, 0.0])
    assert ColliderMode.named("symmetry") is ColliderMode.SYMMETRY
    # the device array holds the same values, and no collider gives one zeroed record (a count of 0)
    arr = wp.array(colliders.collider_records([c, Collider.half_space([0, 0, 0], [0, 0, 1])], 1.0),
                   dtype=colliders.DeviceCollider, device="cpu")
    back = arr.numpy()
    assert back.shape == (2,) and back[0].tobytes() == r.tobytes() and back[1]["kind"] == ColliderKind.HALF_SPACE
    assert colliders.collider_records([], 0.0).shape == (1,)


def test_kernel_sources_compare_names_not_numbers():
    bare = re.compile(r"\b(mode|kind|follows|s|split\[idx\]) *[!=]= *\d|flags *(%|//)")
    found = []
    for name in ("colliders.py", "kernels/grid.py", "kernels/p2g.py", "kernels/g2p.py", "kernels/contact.py",
                 "kernels/stencil.py"):
        for i, line in enumerate((MPM / name).read_text().splitlines(), 1):
            if bare.search(line.split("#")[0]):
                found.append(f"{name}:{i}: {line.strip()}")
    assert not found, "bare integer codes (name them in magsoro.mpm.settings):\n" + "\n".join(found)
