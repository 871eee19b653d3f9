"""The README's animated picture: a learned manager passing an obstacle where `direct` does not.

Plays the run, `sampling` and `direct` on the same seeded episodes of the run's task and writes the GIF
of one episode that the run and `sampling` solve and in which `direct` collides: of those, the one
``pick_episode`` would show (typical start distance, paths that differ most).

Run: python benchmarks/front_page_gif.py RUN_DIR [--out docs/assets/obstacle-scorer.gif] [--episodes 16]
(the committed picture: a run of ``hier-ssl train obstacle/scorer``, seed 0, in a directory named
``obstacle-scorer``). RUN_DIR may be a planner's name, on ``--task`` (default: the run's own task; for a
planner, obstacle): tests/test_benchmarks.py runs it so. The words are ``--fontsize`` points, large
enough to read where the docs show the picture at about half its width.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hier_ssl.evaluation.compare import compare, is_planner
from hier_ssl.evaluation.figures import episode_video, pick_episode
from hier_ssl.world.field import get_field


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--out", type=Path, default=Path("docs/assets/obstacle-scorer.gif"))
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--task", default=None)
    parser.add_argument("--fontsize", type=float, default=16)
    args = parser.parse_args()

    task = args.task or ("obstacle" if is_planner(args.run) else None)
    managers = [args.run, "sampling", "direct"]
    evaluations = compare(
        managers, task=task, episodes=args.episodes, seed=args.seed, record=range(args.episodes)
    )
    run, sampling, direct = (e.result["trajectories"] for e in evaluations)
    shown = [
        j
        for j in range(args.episodes)
        if run[j]["outcome"] == sampling[j]["outcome"] == ["success"]
        and direct[j]["outcome"] == ["collision"]
    ]
    if not shown:
        raise SystemExit(
            f"no episode of the first {args.episodes} where direct collides and both others succeed"
        )
    j = shown[pick_episode([[run[i] for i in shown], [sampling[i] for i in shown]])]
    panels = [(e.name, e.result["trajectories"][j]) for e in evaluations]
    path = episode_video(panels, get_field(evaluations[0].env.field), args.out, fontsize=args.fontsize)
    print(f"wrote {path}: episode {j} of seed {args.seed}, {path.stat().st_size / 1000:.0f} kB")


if __name__ == "__main__":
    main()
