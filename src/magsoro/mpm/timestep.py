"""The explicit time-step (CFL) bound of the engine."""


def cfl_time_step(cfl: float, dx: float, wave_speed: float, max_speed: float = 0.0) -> float:
    """dt = cfl dx / (c + |v|max), s: the largest stable step for grid spacing ``dx`` (m), safety factor ``cfl``,
    wave speed ``wave_speed`` c (m/s, e.g. :meth:`magsoro.mpm.model.Model.wave_speed`) and largest particle
    speed ``max_speed`` (m/s)."""
    return cfl * dx / (wave_speed + max_speed)
