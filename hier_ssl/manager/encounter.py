"""What avoiding a neighbour takes, in closed form: the "encounters" observation's extra columns.

The "neighbours" layout gives each neighbour's relative position and velocity; whether the robot's way
is blocked is a nonlinear function of them (a closest approach) that a small network learns slowly. The
"encounters" layout appends, after the K neighbour slots of ``hier_ssl.manager.neighbours``, 6 values per
slot (same order, nearest first)::

    13+6K+6k  slot k: t_cpa / horizon, d_cpa / max_pos     (both keep their current velocities)
                      t_line / horizon, d_line / max_pos   (the robot heads straight for the target)
                      along / max_pos, across / max_pos    (the neighbour in the robot -> target frame)

t_cpa is the time of closest approach in [0, horizon] s (3 s) and d_cpa the distance then; t_line,
d_line the same for a robot that drives from where it is straight to the target at 2 m/s, counted only
until it gets there (t in [0, distance / speed]); along, across the neighbour's relative position
projected on the robot -> target direction and its left normal. Padding slots are all zeros. Values are
clipped like the rest of the observation.

``encounter_columns`` is written with operators and methods that numpy arrays and torch tensors share, so
the exported manager (``hier_ssl.policies.export``) computes the same numbers with the same code.
"""

from __future__ import annotations

ENCOUNTER_DIM = 6  # values per neighbour slot

# The array arguments carry no annotation: TorchScript compiles these functions into the exported manager,
# and there an unannotated argument is a Tensor; numpy arrays pass through the same operators. TorchScript
# reads no module-level constants, hence the literals and the defaults.


def _closest(rel_pos, rel_vel, t_max):
    """Time in [0, t_max] and distance of the closest approach of a relative motion rel_pos + rel_vel t.

    Shapes: rel_pos, rel_vel (B, K, 2); t_max (B, 1) s. Returns two (B, K) arrays."""
    speed2 = (rel_vel * rel_vel).sum(-1).clip(min=1e-9)
    t = (-(rel_pos * rel_vel).sum(-1) / speed2).clip(min=0.0)
    t = t - (t - t_max).clip(min=0.0)  # min(t, t_max), the same code for numpy and torch
    gap = rel_pos + rel_vel * t[..., None]
    return t, (gap * gap).sum(-1) ** 0.5


def encounter_columns(
    rel_pos,
    rel_vel,
    robot_vel,
    to_target,
    max_pos: float,
    clip: float,
    speed: float = 2.0,
    horizon: float = 3.0,
):
    """The six encounter values of every neighbour slot, normalised and clipped (module docstring).

    Args:
        rel_pos, rel_vel: (B, K, 2) the neighbours' positions and velocities minus the robot's, m and m/s
            (unclipped).
        robot_vel: (B, 1, 2) m/s. to_target: (B, 1, 2) the target's position minus the robot's, m.
        max_pos: m that a value of 1 stands for; clip: the observation's bound.
        speed: m/s of the straight-line approach, about the paper worker's cruise; horizon: s, the latest
            time a constant-velocity closest approach is reported at.

    Returns:
        a list of six (B, K) arrays in the layout's order; numpy in, numpy out, torch in, torch out.
    """
    distance = (to_target * to_target).sum(-1) ** 0.5  # (B, 1)
    t_cpa, d_cpa = _closest(rel_pos, rel_vel, distance * 0.0 + horizon)
    unit = to_target / distance[..., None].clip(min=1e-9)
    # The robot at `speed` along the line in place of its own velocity.
    line_vel = rel_vel + robot_vel - unit * speed
    t_line, d_line = _closest(rel_pos, line_vel, distance / speed)
    along = (rel_pos * unit).sum(-1)
    across = unit[..., 0] * rel_pos[..., 1] - unit[..., 1] * rel_pos[..., 0]
    return [
        (t_cpa / horizon).clip(-clip, clip),
        (d_cpa / max_pos).clip(-clip, clip),
        (t_line / horizon).clip(-clip, clip),
        (d_line / max_pos).clip(-clip, clip),
        (along / max_pos).clip(-clip, clip),
        (across / max_pos).clip(-clip, clip),
    ]


__all__ = ["ENCOUNTER_DIM", "encounter_columns"]
