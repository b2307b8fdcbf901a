"""A random policy against the planner's policy in the Gymnasium environment (navigate on lab).

Both policies play the same episodes of ``bouncesim/Bounce-v0`` (docs/model.md §23): start and
goal configurations drawn once (uniform, distinct, the goal reachable by the planner), one env
seed per episode, for each turn-noise level.

- ``random``: a uniformly random bouncing angle every bounce, until the goal or ``max_steps``.
- ``planner``: the angles of :meth:`planners.navigation.Navigator.plan` for the episode's
  (start, goal), played open loop (the robot only senses bumps and time); when they run out
  before the goal the policy stops and the episode is a failure (the executor's reading of a
  plan, docs/model.md §21).

Outputs in ``--out``: ``episodes.csv`` (one row per episode and policy), ``summary.csv``
(success rates with 95 % Wilson intervals, mean returns with their standard errors),
``config.json`` and ``policies.png`` (drawn from episodes.csv alone).
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from bouncesim.gym import BounceEnv
from bouncesim.plots import save_figure
from planners.cells import CellSpace
from planners.navigation import Navigator

from .common import experiment_parser, output_dir, run_main, write_config
from .nav_montecarlo import wilson

__all__ = ["Config", "draw", "episode", "main", "run", "sample_episodes", "summarise"]

POLICIES = ("random", "planner")


@dataclass(frozen=True)
class Config:
    """Parameters of one gym_policies run.

    Attributes
    ----------
    env : str                  environment
    angles : tuple of float    the bouncing angles Φ [deg] (the action set and the planner's)
    noises : tuple of str      turn-noise levels (docs/model.md §21 forms)
    episodes : int             (start, goal) episodes per noise level
    max_steps : int            bounces before an episode is truncated
    step_cost : float          reward of a bounce that does not reach the goal is −this
    quick : bool               recorded; ``main`` turns it into the quick budget
    seed : int                 root seed (episodes, env seeds, the random policy)
    out : Path                 output folder
    """

    env: str = "lab"
    angles: tuple[float, ...] = (45.0, 90.0, 135.0)
    noises: tuple[str, ...] = ("none", "model:eps=45,r=0.9", "gauss:5")
    episodes: int = 200
    max_steps: int = 100
    step_cost: float = 0.01
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / "gym_policies"


def sample_episodes(env: BounceEnv, nav: Navigator, n: int, rng: np.random.Generator
                    ) -> list[dict]:
    """``n`` episodes: distinct (start, goal) configurations with a plan, whose start's first
    flight does not already reach the goal, and an env seed each.
    """
    out: list[dict] = []
    N = env.cells.N
    while len(out) < n:
        start, goal = (int(v) for v in rng.integers(N, size=2))
        route = nav.plan(start, goal) if start != goal else None
        if route is None:
            continue
        try:
            env.reset(seed=0, options={"start": start, "goal": goal})
        except envs.UserError:              # the first flight already reaches the goal
            continue
        out.append({"start": start, "goal": goal, "seed": int(rng.integers(2**31)),
                    "plan": [env.angles.index(float(a)) for a in route.plan if a != 0]})
    return out


def episode(env: BounceEnv, ep: dict, policy: str, rng: np.random.Generator) -> dict:
    """Play one episode with ``policy`` ('random' or 'planner'); returns its record."""
    env.reset(seed=ep["seed"], options={"start": ep["start"], "goal": ep["goal"]})
    plan = list(ep["plan"])
    total, bounces, end, success = 0.0, 0, "truncated", False
    while True:
        if policy == "random":
            action = int(rng.integers(env.action_space.n))
        elif plan:
            action = plan.pop(0)
        else:
            end = "plan finished"
            break
        _, reward, terminated, truncated, info = env.step(action)
        total += reward
        bounces += 1
        if terminated or truncated:
            success = bool(info["is_success"])
            end = "goal" if success else "truncated"
            break
    return {"policy": policy, "start": ep["start"], "goal": ep["goal"], "seed": ep["seed"],
            "plan_bounces": len(ep["plan"]), "success": success, "bounces": bounces,
            "return": total, "end": end}


def summarise(episodes: pd.DataFrame) -> pd.DataFrame:
    """Per noise level and policy: success rate (95 % Wilson interval) and mean return."""
    g = episodes.groupby(["noise", "policy"], sort=False)
    s = g.agg(episodes=("success", "size"), successes=("success", "sum"),
              mean_return=("return", "mean"), sd_return=("return", "std"),
              mean_bounces=("bounces", "mean")).reset_index()
    s["success_rate"] = s["successes"] / s["episodes"]
    s["ci_low"], s["ci_high"] = wilson(s["successes"].to_numpy(), s["episodes"].to_numpy())
    s["return_sem"] = s["sd_return"] / np.sqrt(s["episodes"])
    return s.drop(columns="sd_return")


def draw(episodes_csv: Path, path: Path) -> None:
    """Success rate and mean return per noise level and policy (from episodes.csv alone)."""
    import matplotlib.pyplot as plt
    s = summarise(pd.read_csv(episodes_csv))
    noises = list(dict.fromkeys(s["noise"]))
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    x = np.arange(len(noises))
    width = 0.38
    colors = {"random": "#999999", "planner": "#1f77b4"}
    for i, policy in enumerate(POLICIES):
        row = s[s["policy"] == policy].set_index("noise").loc[noises]
        rate = row["success_rate"].to_numpy()
        err = np.vstack([rate - row["ci_low"], row["ci_high"] - rate])
        axes[0].bar(x + (i - 0.5) * width, rate, width, yerr=err, capsize=3,
                    color=colors[policy], label=policy)
        axes[1].bar(x + (i - 0.5) * width, row["mean_return"], width,
                    yerr=1.96 * row["return_sem"], capsize=3, color=colors[policy],
                    label=policy)
    n = int(s["episodes"].iloc[0])
    axes[0].set_ylabel("success rate (95 % Wilson)")
    axes[0].set_ylim(0, 1.05)
    axes[1].set_ylabel("mean return (±1.96 s.e.)")
    axes[1].axhline(0, color="black", lw=0.6)
    for ax in axes:
        ax.set_xticks(x, noises, fontsize=8)
        ax.set_xlabel("turn noise")
    axes[0].legend(fontsize=8, loc="upper right")
    fig.suptitle(f"Bounce-v0 navigate: random vs planner policy, {n} episodes per noise",
                 fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def run(config: Config) -> Path:
    """Play every episode with both policies, write the CSVs, config.json and the figure."""
    if config.episodes < 1:
        raise envs.UserError(f"--episodes must be at least 1, got {config.episodes}.")
    out = output_dir(config.out)
    room = envs.load(config.env)
    nav = Navigator(CellSpace(room), config.angles)
    root = np.random.SeedSequence(config.seed)
    ep_seq, pol_seq = root.spawn(2)
    probe = BounceEnv(room, "navigate", angles=config.angles)
    eps = sample_episodes(probe, nav, config.episodes, np.random.default_rng(ep_seq))
    rows = []
    for noise, seq in zip(config.noises, pol_seq.spawn(len(config.noises))):
        env = BounceEnv(room, "navigate", angles=config.angles, noise=noise,
                        max_steps=config.max_steps, step_cost=config.step_cost)
        rng = np.random.default_rng(seq)          # the random policy's actions at this level
        for i, ep in enumerate(eps):
            for policy in POLICIES:
                rows.append({"noise": noise, "episode": i, **episode(env, ep, policy, rng)})
    table = pd.DataFrame(rows)
    table.to_csv(out / "episodes.csv", index=False)
    summary = summarise(table)
    summary.to_csv(out / "summary.csv", index=False)
    write_config(out, {"experiment": "gym_policies", **asdict(config),
                       "env_id": "bouncesim/Bounce-v0", "task": "navigate",
                       "episodes_sampling": "start, goal uniform over the configurations, "
                       "distinct, planner-reachable, first flight not already at the goal",
                       "planner_policy": "Navigator.plan angles open loop (w1 = 1, w2 = 100); "
                       "stops (failure) when they run out before the goal",
                       "confidence_intervals": "95 % Wilson score (scipy.stats.binomtest)"})
    draw(out / "episodes.csv", out / "policies.png")
    cols = ["noise", "policy", "episodes", "success_rate", "ci_low", "ci_high", "mean_return",
            "return_sem", "mean_bounces"]
    print(summary[cols].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    p = experiment_parser("gym_policies", __doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=None,
                   help="episodes per noise level (default 200; 12 with --quick)")
    p.add_argument("--env", default="lab", help="environment (default lab)")
    args = p.parse_args(argv)
    episodes = args.episodes if args.episodes is not None else (12 if args.quick else 200)
    return run_main("gym_policies", lambda: Config(
        env=args.env, episodes=episodes, quick=args.quick, seed=args.seed, out=args.out), run)


if __name__ == "__main__":
    sys.exit(main())
