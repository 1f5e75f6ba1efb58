"""Contact between bodies and within a body: two velocity fields per grid node, Coulomb friction, free separation.

Method (multi-field grid contact, after Bardenhagen et al. 2001, with the fields chosen per node):

1. Scan (particles, ``contact_scan`` in :mod:`magsoro.mpm.kernels`, on the transfers' stencil): every node records the smallest and largest contact group that reaches it; with self-contact
   on it also sums m, m X and m X X^T of the reference positions X of the particles that reach it.
2. Classify (nodes): a node is *split* into two fields when two groups meet there (field 0 = the smallest group,
   field 1 = every other) or, for self-contact, when the reference positions of its particles spread over more
   than the stencil of a continuous body (largest standard deviation > ``spread`` cells: two layers of one body
   that were more than about 2 x spread cells apart before it folded); field 1 is then the particles on the +a
   side of the plane through their mean reference position normal to the principal axis a of the spread.
   A sticky pair is never split: its bodies share one velocity field, as a single body.
3. Transfers: p2g scatters each particle into the field it belongs to at that node (grid arrays are doubled:
   field f of node i at slot i + f n), with the mass gradient sum m_p w_ip (x_i - x_p); g2p gathers from the same
   field, so a particle only ever sees its own field's velocity.
4. Resolve (nodes, after each field's free velocity, walls and colliders), only where the fields' local centroids
   (weights w_ip m_p) are closer than ``gap`` cells and, at BODIES nodes, both fields hold at least
   ``MIN_FRACTION`` of the node's mass: with n the unit normal from the *heavier* field's mass gradient at BODIES
   nodes (g_0 / |g_0| when m_0 >= m_1, else -g_1 / |g_1|, g_f = sum m_p w_ip (x_i - x_p) / dx), along
   g_0 / m_0 - g_1 / m_1 at FOLD nodes (both pointing from field 0 towards field 1), and v_cm the centre-of-mass
   velocity, field 0 is approaching when d = (v_0 - v_cm) . n > 0. Then its normal relative velocity is removed and
   its tangential relative velocity t shrinks by mu d (Coulomb), stopping at zero:
       v_0' = v_cm + t max(|t| - mu d, 0) / |t|,     v_1' = v_1 - (m_0 / m_1) (v_0' - v_0)
   which conserves the node's momentum. Separating fields (d <= 0) move freely: no adhesion.
   Why: a field that holds only the tails of its outermost particles' weights at a node (under a tenth of the
   node's mass) has a velocity extrapolated a cell or more beyond its particles, and its centroid direction is that
   of its nearest particles, tilted round a body's corner; counting such nodes put a sliding block's load on its
   corners, with normals tilted against the motion (docs/engine.md, "Contact"). FOLD nodes keep the centroid
   normal and no threshold: with them the folded strip of ``magsoro validate self_contact`` closed to 0.45 cells.

Limits: fields interact once their stencils share nodes, so bodies touch at a gap of about one cell; three or more
groups at one node are resolved as the smallest against the rest; a CPU step with contact runs on one thread.
"""

import functools

import warp as wp

from magsoro.mpm.settings import NodeClass

#: Node classes of the classify pass (:class:`magsoro.mpm.settings.NodeClass`)
SINGLE = wp.constant(int(NodeClass.SINGLE))  # one velocity field
BODIES = wp.constant(int(NodeClass.BODIES))  # two contact groups meet
FOLD = wp.constant(int(NodeClass.FOLD))  # two layers of one body (self-contact)

#: Smallest share of a node's mass each field must hold for the node to resolve contact (step 4)
MIN_FRACTION = wp.constant(0.1)


@functools.cache
def make_contact(dim: int, scalar):
    """Contact struct, device functions and kernels for ``dim`` in (2, 3) and ``scalar`` in (wp.float32, wp.float64)."""
    vec = wp.types.vector(length=dim, dtype=scalar)
    mat = wp.types.matrix(shape=(dim, dim), dtype=scalar)

    @wp.struct
    class ContactGrid:
        """What the transfers need to know of contact. ``active`` 0: one field everywhere (the arrays may be
        empty); ``n_nodes``: nodes of the grid block (slot of field 1 of node i: i + n_nodes)."""

        active: int
        n_nodes: int
        gap: scalar  # contact when the fields' local centroids are closer than this, cells
        group: wp.array(dtype=wp.int32)  # per particle: contact group
        X: wp.array(dtype=vec)  # per particle: reference position, m
        split: wp.array(dtype=wp.int32)  # per node: SINGLE, BODIES or FOLD
        gmin: wp.array(dtype=wp.int32)  # per node: smallest group reaching it
        xbar: wp.array(dtype=vec)  # per node (FOLD): mean reference position, m
        axis: wp.array(dtype=vec)  # per node (FOLD): principal axis of the reference spread
        mu: wp.array(dtype=scalar)  # per node: Coulomb coefficient of the pair meeting there
        grad_m: wp.array(dtype=vec)  # per slot: mass gradient sum m_p w_ip (x_i - x_p) / dx, kg

    @wp.func
    def field_of(ct: wp.array(dtype=ContactGrid), p: int, idx: int):
        """Field (0 or 1) particle ``p`` belongs to at node ``idx``. The kernels take the struct as a one-element
        array: a struct argument is copied for every thread of a CPU launch, an array of it is not."""
        f = int(0)
        if ct[0].active != 0:
            s = ct[0].split[idx]
            if s == BODIES:
                if ct[0].group[p] != ct[0].gmin[idx]:
                    f = 1
            elif s == FOLD:
                if wp.dot(ct[0].X[p] - ct[0].xbar[idx], ct[0].axis[idx]) > scalar(0.0):
                    f = 1
        return f

    @wp.func
    def resolve(v0: vec, v1: vec, m0: scalar, m1: scalar, g0: vec, g1: vec, mu: scalar, gap: scalar, bodies: int):
        """Contact correction of the two fields of a node (module docstring, step 4); ``bodies`` != 0: the node is
        split between two contact groups (BODIES), else two layers of one body (FOLD)."""
        # g_f / m_f = (x_i - xbar_f) / dx with xbar_f the field's local centroid (weights w_ip m_p)
        sep = g0 / m0 - g1 / m1
        n = sep
        if bodies != 0:
            if wp.min(m0, m1) < scalar(MIN_FRACTION) * (m0 + m1):
                return v0, v1  # one field is only the weight tails of its outermost particles: no contact here
            # normal from the heavier field: the body the node lies in or at; the lighter one may be a corner
            # passing over it, whose centroid direction tilts round the corner
            n = -g1
            if m0 >= m1:
                n = g0
        if wp.length(sep) > gap:
            return v0, v1  # the fields' local centroids are further apart than touching surfaces' would be
        ln = wp.length(n)
        if ln <= scalar(0.0):
            return v0, v1
        n = n / ln
        vcm = (m0 * v0 + m1 * v1) / (m0 + m1)
        rel = v0 - vcm
        d = wp.dot(rel, n)
        if d <= scalar(0.0):
            return v0, v1  # separating or sliding apart: no contact force
        t = rel - d * n
        tl = wp.length(t)
        keep = scalar(0.0)
        if tl > scalar(0.0):
            keep = wp.max(tl - mu * d, scalar(0.0)) / tl
        new0 = vcm + keep * t
        return new0, v1 - (m0 / m1) * (new0 - v0)

    @wp.func
    def principal_axis(cov: mat):
        """Largest eigenvalue and its unit eigenvector of a symmetric positive semi-definite matrix (power
        iteration from its longest column, which has a component along the leading eigenvector)."""
        best = scalar(-1.0)
        v = vec()
        for a in range(dim):
            col = vec()
            for b in range(dim):
                col[b] = cov[b, a]
            c = wp.dot(col, col)
            if c > best:
                best = c
                v = col
        lv = wp.length(v)
        if lv <= scalar(0.0):
            return scalar(0.0), v
        v = v / lv
        for _ in range(16):
            w = cov * v
            lw = wp.length(w)
            if lw <= scalar(0.0):
                return scalar(0.0), v
            v = w / lw
        return wp.dot(v, cov * v), v

    @wp.kernel(enable_backward=False)
    def contact_classify(
        gmin: wp.array(dtype=wp.int32),
        gmax: wp.array(dtype=wp.int32),
        moments: wp.array(dtype=scalar),
        fold: int,
        spread2: scalar,
        friction: wp.array(dtype=scalar),
        n_groups: int,
        split: wp.array(dtype=wp.int32),
        xbar: wp.array(dtype=vec),
        axis: wp.array(dtype=vec),
        mu: wp.array(dtype=scalar),
    ):
        """Step 2. ``friction`` is the n_groups x n_groups table of Coulomb coefficients (negative: sticky);
        ``spread2`` the squared spread (m^2) above which a node's reference positions are two layers."""
        idx = wp.tid()
        a = gmin[idx]
        b = gmax[idx]
        s = int(SINGLE)
        if a >= 0 and a < b:
            c = friction[a * n_groups + b]
            if c >= scalar(0.0):
                s = BODIES
                mu[idx] = c
        elif a == b and fold != 0:
            # one group reaches the node (an empty node has a > b: it must not index the friction table, where
            # a * n_groups overflows)
            c = friction[a * n_groups + a]
            stride = 1 + dim + dim * dim
            row = idx * stride
            m = moments[row]
            if c >= scalar(0.0) and m > scalar(0.0):
                mean = vec()
                for i in range(dim):
                    mean[i] = moments[row + 1 + i] / m
                cov = mat()
                for i in range(dim):
                    for j in range(dim):
                        cov[i, j] = moments[row + 1 + dim + i * dim + j] / m - mean[i] * mean[j]
                lam, e = principal_axis(cov)
                if lam > spread2:
                    s = FOLD
                    xbar[idx] = mean
                    axis[idx] = e
                    mu[idx] = c
        split[idx] = s

    return dict(ContactGrid=ContactGrid, field_of=field_of, resolve=resolve, contact_classify=contact_classify)


def launch_contact_classify(kernels, n, *, gmin, gmax, moments, fold, spread2, friction, n_groups, split, xbar, axis,
                            mu, device, record=False):
    """``contact_classify`` over ``n`` nodes (step 2); ``kernels``: :func:`make_contact`'s table or the engine's
    (:func:`magsoro.mpm.kernels.make_kernels`). Returns Warp's recorded launch with ``record``. The one place
    its argument order is written."""
    return wp.launch(kernels["contact_classify"], dim=n, device=device, record_cmd=record,
                     inputs=[gmin, gmax, moments, fold, spread2, friction, n_groups, split, xbar, axis, mu])
