"""Richardson extrapolation of results computed at several grid spacings: the observed order of convergence, the
extrapolated (grid-independent) value and the uncertainty of the finest result.

Values ``f`` at spacings ``h`` that converge like ``f(h) = f0 + C h^p`` give ``p`` and ``f0`` from three of them.
With ``h1 < h2 < h3`` (1 the finest), ``e21 = f2 - f1``, ``e32 = f3 - f2``, ``r21 = h2 / h1``, ``r32 = h3 / h2`` and
``s = sign(e32 / e21)``, the order solves (Celik et al. 2008, the ASME procedure for grids refined by unequal
ratios)::

    p ln r21 = | ln |e32 / e21| + ln((r21^p - s) / (r32^p - s)) |

and then ``f0 = (r21^p f1 - f2) / (r21^p - 1)``; the finest value's uncertainty is Roache's (1994) grid
convergence index ``GCI = 1.25 |f1 - f2| / (r21^p - 1)``. When the differences change sign (``s < 0``) the values
oscillate: they are not in the range where one power of ``h`` dominates, no order is claimed, and the uncertainty
is half the spread of the three values. Values that agree to round-off are converged as they stand.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

#: safety factor of the grid convergence index for three or more grids (Roache 1994)
GCI_SAFETY = 1.25
#: orders searched for (outside this range the data do not follow one power of h)
ORDER_RANGE = (0.05, 12.0)
#: differences below this fraction of the value are round-off, not discretisation error
ROUND_OFF = 1e-10
#: a quantity whose values all stay below this fraction of its scale (``estimate(..., scale=)``: e.g. the largest
#: component of the same probe) is zero, by symmetry, to round-off: float32 runs carry relative noise near 1e-7,
#: float64 runs whose steps stop at a residual tolerance near 1e-8
ZERO = 1e-6


@dataclass
class Triple:
    """The order seen by three consecutive spacings (None when their values oscillate or follow no power law)."""

    h: list[float]
    values: list[float]
    order: float | None
    behaviour: str


@dataclass
class Estimate:
    """What the values at the spacings ``h`` (coarse to fine) say about the grid-independent value.

    ``behaviour``: 'monotone' (the finest three converge one way: ``order`` and ``extrapolated`` are given),
    'oscillating' (they do not), 'converged' (they agree to round-off), 'two spacings' (an order only when one was
    assumed, ``assumed_order``), 'no power law' (monotone, but no order in ORDER_RANGE fits).
    ``value`` is the best estimate (the extrapolated value, else the finest) and ``uncertainty`` its band (GCI,
    or half the spread of the finest three); ``triples`` the order from each run of three consecutive spacings,
    coarse to fine, which shows whether the order has settled."""

    h: list[float]
    values: list[float]
    behaviour: str
    value: float
    uncertainty: float | None
    order: float | None = None
    extrapolated: float | None = None
    gci: float | None = None  # relative to the finest value
    assumed_order: float | None = None
    triples: list[Triple] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)

    def summary(self) -> str:
        """One line for a terminal."""
        band = f" +- {self.uncertainty:.4g}" if self.uncertainty is not None else ""
        if self.behaviour == "monotone":
            how = (f"order {self.order:.2f}" if self.assumed_order is None else f"order {self.order:g} (assumed)")
            return f"extrapolated {self.value:.6g}{band} ({how}; finest {self.values[-1]:.6g})"
        if self.behaviour == "oscillating":
            return f"finest {self.value:.6g}{band} (values oscillate: no order; band half the finest three's spread)"
        if self.behaviour == "converged":
            return f"{self.value:.6g} (the finest values agree to round-off)"
        if self.behaviour == "zero":
            return f"0 (every value within {self.uncertainty:.3g} of zero, under {ZERO:g} of the probe's scale: zero by symmetry)"
        if self.behaviour == "no power law":
            return f"finest {self.value:.6g}{band} (monotone, but no order between {ORDER_RANGE[0]:g} and {ORDER_RANGE[1]:g} fits)"
        return f"finest {self.value:.6g}, change from the coarser {self.values[-1] - self.values[-2]:+.4g} (give a third spacing, or --order)"


def observed_order(h, f) -> float | None:
    """The order ``p`` of three values ``f`` at spacings ``h`` (any order of the inputs), or None when they oscillate
    or no ``p`` in ORDER_RANGE fits."""
    h, f = _sorted(h, f)
    (h1, h2, h3), (f1, f2, f3) = h[::-1], f[::-1]  # 1 the finest
    e21, e32 = f2 - f1, f3 - f2
    scale = max(abs(f1), abs(f2), abs(f3), 1e-300)
    if abs(e21) <= ROUND_OFF * scale or abs(e32) <= ROUND_OFF * scale or e32 * e21 < 0:
        return None
    r21, r32 = h2 / h1, h3 / h2
    ratio = math.log(abs(e32 / e21))

    def g(p):
        return p * math.log(r21) - abs(ratio + math.log((r21 ** p - 1.0) / (r32 ** p - 1.0)))

    lo, hi = ORDER_RANGE
    ps = np.geomspace(lo, hi, 200)
    gs = [g(p) for p in ps]
    for a, b, ga, gb in zip(ps[:-1], ps[1:], gs[:-1], gs[1:]):
        if ga == 0.0:
            return float(a)
        if ga * gb < 0.0:
            from scipy.optimize import brentq

            return float(brentq(g, a, b, xtol=1e-12))
    return None


def estimate(h, values, order: float | None = None, scale: float | None = None) -> Estimate:
    """Richardson estimate from ``values`` at spacings ``h`` (two or more, any order); ``order``: assume this
    order instead of measuring it (needed with two spacings); ``scale``: the size of the quantity's kind (e.g. the
    largest component of the same probe), below ZERO of which every value is zero by symmetry."""
    h, f = _sorted(h, values)
    if len(h) < 2:
        raise ValueError("a convergence estimate needs values at two or more spacings")
    if len(set(h)) != len(h):
        raise ValueError("the spacings must differ")
    if scale is not None and scale > 0 and max(abs(v) for v in f) <= ZERO * scale:
        return Estimate(h, f, "zero", 0.0, float(max(abs(v) for v in f)))
    triples = []
    for i in range(len(h) - 2):
        p = observed_order(h[i:i + 3], f[i:i + 3])
        e1, e2 = f[i + 1] - f[i], f[i + 2] - f[i + 1]
        how = "monotone" if p is not None else ("oscillating" if e1 * e2 < 0 else "converged" if e1 == e2 == 0 else "no power law")
        triples.append(Triple(h[i:i + 3], f[i:i + 3], p, how))
    f1, f2 = f[-1], f[-2]
    r21 = h[-2] / h[-1]
    scale = max(abs(f1), 1e-300)
    if abs(f1 - f2) <= ROUND_OFF * scale and (len(f) < 3 or abs(f2 - f[-3]) <= ROUND_OFF * scale):
        return Estimate(h, f, "converged", f1, 0.0, triples=triples)
    if order is not None:
        if not (order > 0 and math.isfinite(order)):
            raise ValueError(f"the assumed order must be a finite number > 0, got {order}")
        return _extrapolate(h, f, order, r21, triples, assumed=order)
    if len(h) == 2:
        return Estimate(h, f, "two spacings", f1, abs(f1 - f2), triples=triples)
    last = triples[-1]
    if last.behaviour == "oscillating":
        spread = max(f[-3:]) - min(f[-3:])
        return Estimate(h, f, "oscillating", f1, 0.5 * spread, triples=triples)
    if last.order is None:
        return Estimate(h, f, "no power law", f1, abs(f1 - f2), triples=triples)
    return _extrapolate(h, f, last.order, r21, triples)


def _extrapolate(h, f, p, r21, triples, assumed=None) -> Estimate:
    f1, f2 = f[-1], f[-2]
    k = r21 ** p - 1.0
    f0 = f1 + (f1 - f2) / k
    band = GCI_SAFETY * abs(f1 - f2) / k
    gci = band / abs(f1) if f1 != 0 else None
    return Estimate(h, f, "monotone", f0, band, order=p, extrapolated=f0, gci=gci, assumed_order=assumed,
                    triples=triples)


def _sorted(h, f):
    """(h, f) as float lists, coarse (largest h) first."""
    h = [float(x) for x in h]
    f = [float(x) for x in f]
    if len(h) != len(f):
        raise ValueError("one value per spacing")
    if any(not (x > 0 and math.isfinite(x)) for x in h):
        raise ValueError("spacings must be finite and > 0")
    if any(not math.isfinite(x) for x in f):
        raise ValueError("values must be finite")
    order = sorted(range(len(h)), key=lambda i: -h[i])
    return [h[i] for i in order], [f[i] for i in order]
