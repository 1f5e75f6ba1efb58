"""Differentiable simulation: gradients of a loss on the final (or time-integrated) state with respect to
magnetisation, applied field, magnet pose and material, on Warp's autodiff (docs/differentiable.md)."""

from magsoro.diff.rollout import DiffError, Rollout

__all__ = ["DiffError", "Rollout"]
