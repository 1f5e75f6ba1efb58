"""Grid convergence studies: a scene run at several spacings (``magsoro converge``) and the Richardson estimate of
its grid-independent results (:mod:`magsoro.convergence.richardson`)."""

from magsoro.convergence.richardson import Estimate, estimate, observed_order

__all__ = ["Estimate", "estimate", "observed_order"]
