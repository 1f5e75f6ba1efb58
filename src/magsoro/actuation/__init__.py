"""Actuation tools of seed 004 (magnetic soft growing robot).

- :mod:`magsoro.actuation.eversion`: pressure and tip force of an everting magnetoelastic tube (eqs 1-13) and the
  minimum field for pressure-free growth (``magsoro evert``).
- :mod:`magsoro.actuation.sensing`: shape sensing from Hall sensors and magnetic markers (eqs 17-23)
  (``magsoro sense``).
- :mod:`magsoro.actuation.planning`: pseudo-rigid-body model of a planar magnetic continuum robot and the
  time-stepping optimisation of the external-magnet pose sequence (sec II-C) (``magsoro plan``).
- :mod:`magsoro.actuation.replay`: the plan replayed by the MPM engine, growth included.

Submodules load lazily so that ``import magsoro.actuation`` stays cheap.
"""
