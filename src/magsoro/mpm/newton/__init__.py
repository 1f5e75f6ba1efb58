"""The Newton solvers on the reference grid: the quasi-static solver (static), the implicit integrator (implicit),
their contact terms (static_contact: rigid colliders; body_contact: between bodies and within one) and the linear
solvers of their tangents (linear)."""
