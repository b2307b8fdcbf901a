"""Table I of the paper: the policy mix over Φ = {30°, 75°, 315°} on the complex environment.

Algorithm 3 (docs/model.md §16) on the complex environment at 360 orientations (N = 65880) with
ε = 5°, r = 0.8 and the uniform target over position cells: the persistent groups and the
limiting distribution of each bouncing angle, and the mix α minimising ‖Aα − b‖₂. The paper
reports α = (0.22138172, 0.28005791, 0.49856037).

Outputs (under ``--out``, default results/coverage_table1/):

- ``table1.csv``: angle, alpha (uniform target over position cells, docs/model.md §16's default;
  ``--models step,event`` adds ``alpha_event``, the mix designed on the event model),
  alpha_configurations (uniform target over the N configurations, the paper's n = N),
  alpha_paper, persistent groups, largest group, group sizes, transient fraction (one row
  per angle);
- ``coverage.csv``: angle, p, i, j, x, y, q (each angle's coverage, ``mix`` = Aα,
  ``target`` = b);
- ``groups.csv``: angle, z, p, k, group for every persistent configuration;
- ``config.json``: parameters, residual, TV, run time, versions;
- ``fig9_groups_<angle>.png`` (persistent groups on the map at headings 0°, 90°, 180°,
  270°), ``fig10_limiting.png`` (coverage of each angle), ``fig11_mix_vs_target.png``.
  The figures are drawn from the CSV files alone.

``--quick`` uses K = 72 (5° steps), so the same angles and ε stay valid.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import envs
from experiments.common import (
    add_models_arg,
    experiment_parser,
    output_dir,
    run_main,
    write_config,
)
from experiments.compare import add_compare_arg
from planners.cells import CellSpace
from planners.coverage import TurnNoise, design_mix, model_for, solve_mix, uniform_target

__all__ = ["PAPER_ALPHA", "Config", "draw_figures", "main", "run"]

NAME = "coverage_table1"
ANGLES = (30.0, 75.0, 315.0)
PAPER_ALPHA = (0.22138172, 0.28005791, 0.49856037)
EPS, R = 5.0, 0.8
ENV = "complex"


def _num(x):
    x = float(x)
    return int(round(x)) if abs(x - round(x)) < 1e-9 else x


def write_csvs(out: Path, cs: CellSpace, res, conf_mix) -> None:
    """table1.csv, coverage.csv and groups.csv from a MixDesign (positions target) and the
    MixFit of the same chains against the uniform target over configurations.
    """
    rows = []
    for a, al, alc, pa in zip(res.angles, res.alpha, conf_mix.alpha, PAPER_ALPHA):
        ac = res.per_angle[res.angles.index(a)]
        rows.append({"angle": _num(a), "alpha": float(al),
                     "alpha_configurations": float(alc), "alpha_paper": pa,
                     "persistent_groups": ac.analysis.n_groups,
                     "largest_group": int(ac.group_sizes.max()),
                     "group_sizes": ";".join(str(int(s)) for s in ac.group_sizes),
                     "transient_fraction": ac.transient_fraction})
    pd.DataFrame(rows).to_csv(out / "table1.csv", index=False)
    ij, xy = cs.cells_ij, cs.centres
    series = [(_num(ac.angle), ac.q) for ac in res.per_angle]
    series += [("mix", res.mixed_q()), ("target", res.target)]
    cov = pd.concat([pd.DataFrame({"angle": str(n), "p": np.arange(cs.P), "i": ij[:, 0],
                                   "j": ij[:, 1], "x": xy[:, 0], "y": xy[:, 1], "q": q})
                     for n, q in series])
    cov.to_csv(out / "coverage.csv", index=False, float_format="%.10g")
    parts = []
    for ac in res.per_angle:
        lab = ac.analysis.group_labels()
        z = np.flatnonzero(lab >= 0)
        parts.append(pd.DataFrame({"angle": _num(ac.angle), "z": z, "p": z % cs.P,
                                   "k": z // cs.P, "group": lab[z]}))
    pd.concat(parts).to_csv(out / "groups.csv", index=False)


def draw_figures(out: Path, cs: CellSpace) -> list[Path]:
    """Figures 9-11 analogues, drawn from table1.csv, coverage.csv and groups.csv."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bouncesim.coverage_plots import heatmap, save_group_slices, save_mix_vs_target
    from bouncesim.plots import save_figure
    table = pd.read_csv(out / "table1.csv")
    cov = pd.read_csv(out / "coverage.csv", dtype={"angle": str})
    groups = pd.read_csv(out / "groups.csv")
    paths = []
    K = cs.K
    slices = [0, K // 4, K // 2, 3 * K // 4]
    for angle in table["angle"]:
        g = groups[groups["angle"] == angle]
        lab = np.full(cs.N, -1)
        lab[g["z"].to_numpy()] = g["group"].to_numpy()
        paths.append(save_group_slices(
            out / f"fig9_groups_{angle}.png", cs, lab, slices,
            title=f"{angle}°: persistent groups ({g['group'].nunique()}), "
                  f"coloured by group; arrows = heading"))

    def q_of(name):
        d = cov[cov["angle"] == str(name)].sort_values("p")
        return d["q"].to_numpy()

    vmax = max(q_of(a).max() for a in table["angle"])
    fig, axes = plt.subplots(1, len(table), figsize=(5.4 * len(table), 4.6))
    for ax, angle, al in zip(np.atleast_1d(axes), table["angle"], table["alpha"]):
        heatmap(ax, cs, q_of(angle), vmax=vmax,
                title=f"{angle}°: limiting coverage (α = {al:.3f})")
    fig.suptitle(f"complex, K={K}, ε={_num(EPS)}°, r={R}: coverage of each bouncing angle")
    paths.append(save_figure(fig, out / "fig10_limiting.png", dpi=110))
    alpha_txt = ", ".join(f"{a}°: {al:.3f}" for a, al in zip(table["angle"], table["alpha"]))
    paths.append(save_mix_vs_target(out / "fig11_mix_vs_target.png", cs, q_of("mix"),
                                    q_of("target"), title=f"α = {alpha_txt}"))
    return paths


def compare(table: pd.DataFrame, column: str = "alpha") -> list[str]:
    """Sentences saying what matches the paper's Table I and what does not."""
    ours = table[column].to_numpy()
    paper = table["alpha_paper"].to_numpy()
    angles = table["angle"].tolist()
    lines = []
    dom_o, dom_p = angles[int(np.argmax(ours))], angles[int(np.argmax(paper))]
    if dom_o == dom_p:
        lines.append(f"matches: {dom_o}° gets the largest weight, as in the paper "
                     f"({ours.max():.3f} here, {paper.max():.3f} there).")
    else:
        lines.append(f"differs: {dom_o}° gets the largest weight here, {dom_p}° in the paper.")
    order_o = [angles[i] for i in np.argsort(-ours)]
    order_p = [angles[i] for i in np.argsort(-paper)]
    same = order_o == order_p
    lines.append(f"{'matches' if same else 'differs'}: ranking here "
                 f"{' > '.join(f'{a}°' for a in order_o)}, paper "
                 f"{' > '.join(f'{a}°' for a in order_p)}.")
    zero = [a for a, v in zip(angles, ours) if v < 1e-9]
    if zero:
        lines.append(f"differs: {', '.join(f'{a}°' for a in zero)} gets weight 0 here (all "
                     "three angles are used in the paper).")
    lines.append(f"max |alpha - alpha_paper| = {np.abs(ours - paper).max():.3f}.")
    return lines


@dataclass(frozen=True)
class Config:
    """Parameters of one coverage_table1 run (written to ``config.json``).

    Attributes
    ----------
    models : tuple of str     the paper's step model first; each other adds alpha_<model>
    quick : bool              K = 72 instead of 360
    seed : int                recorded only: the computation is deterministic
    out : Path                output folder
    """

    models: tuple[str, ...] = ("step",)
    quick: bool = False
    seed: int = 0
    out: Path = Path("results") / NAME


def run(config: Config) -> Path:
    """Table I and Figs. 9-11 analogues: the CSVs, the figures and config.json.

    Returns the output folder.
    """
    models = config.models
    noise = TurnNoise(EPS, R)
    K = 72 if config.quick else 360
    out = output_dir(config.out)
    env = envs.load(ENV, orientations=K)
    cs = CellSpace(env)
    t0 = time.perf_counter()
    _ = cs.forward
    t_fwd = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = design_mix(model_for(cs), ANGLES, noise)
    t_pipe = time.perf_counter() - t0
    # The same chains against the uniform target over the N configurations (the paper's n = N).
    conf_mix = solve_mix(np.column_stack([ac.pi for ac in res.per_angle]),
                         uniform_target(cs, "configurations"))
    write_csvs(out, cs, res, conf_mix)
    table = pd.read_csv(out / "table1.csv")
    extra = {}
    for m in models:
        if m == "step":
            continue
        t0 = time.perf_counter()
        mres = design_mix(model_for(cs, m), ANGLES, noise)
        extra[m] = {"alpha": mres.alpha.tolist(), "tv": mres.tv,
                    "residual_2norm": mres.residual, "seconds": time.perf_counter() - t0}
        table[f"alpha_{m}"] = mres.alpha
    table.to_csv(out / "table1.csv", index=False)
    sentences = compare(table)
    sentences_conf = compare(table, "alpha_configurations")
    write_config(out, {
        "experiment": NAME, **asdict(config),
        "note": "deterministic: the seed is recorded but not used",
        "params": {"env": ENV, "K": K, "P": cs.P, "N": cs.N, "angles": list(ANGLES),
                   "eps_deg": EPS, "r": R, "target": "uniform over position cells"},
        "results": {"alpha": res.alpha.tolist(), "alpha_paper": list(PAPER_ALPHA),
                    "residual_2norm": res.residual, "tv": res.tv,
                    "comparison": sentences,
                    "configurations_target": {
                        "alpha": conf_mix.alpha.tolist(), "residual_2norm": conf_mix.residual,
                        "tv": conf_mix.tv, "comparison": sentences_conf},
                    "other_models": extra},
        "timing_s": {"step_table": t_fwd, "pipeline": t_pipe}})
    draw_figures(out, cs)
    print(f"Table I analogue: {ENV}, K={K} (N={cs.N}), eps={_num(EPS)}°, r={R}, "
          f"uniform target; pipeline {t_pipe:.2f} s (+ step table {t_fwd:.2f} s)")
    print(f"{'angle':>6} {'alpha':>11} {'alpha conf.':>11} {'paper':>11} {'groups':>7} "
          f"{'largest':>8} {'transient':>10}" + "".join(f" {'alpha ' + m:>13}" for m in extra))
    for r in table.to_dict("records"):
        print(f"{str(r['angle']) + '°':>6} {r['alpha']:11.8f} "
              f"{r['alpha_configurations']:11.8f} {r['alpha_paper']:11.8f} "
              f"{int(r['persistent_groups']):7d} {int(r['largest_group']):8d} "
              f"{100 * r['transient_fraction']:9.1f}%"
              + "".join(f" {r['alpha_' + m]:13.8f}" for m in extra))
    print("alpha: target uniform over the P position cells (docs/model.md §16 default); "
          "alpha conf.: target uniform over the N configurations (the paper's n = N)")
    print(f"positions: residual ||A alpha - b||_2 = {res.residual:.6g}, "
          f"TV = {res.tv:.4f}")
    for s in sentences:
        print("  " + s)
    print(f"configurations: residual = {conf_mix.residual:.6g}, TV = {conf_mix.tv:.4f}")
    for s in sentences_conf:
        print("  " + s)
    print(f"wrote {out}/")
    return out


def main(argv=None) -> int:
    """Parse the command line into a :class:`Config` and :func:`run` it (exit status)."""
    ap = experiment_parser(NAME, "Policy mix over 30°, 75°, 315° on the complex environment "
                           "(the paper's Table I) with Figs. 9-11 analogues.")
    add_models_arg(ap, "step", "each model after the paper's step model adds a column "
                   "alpha_<model> to table1.csv (e.g. step,event)")
    add_compare_arg(ap, NAME)
    args = ap.parse_args(argv)
    return run_main(NAME, lambda: Config(models=tuple(args.models), quick=args.quick,
                                         seed=args.seed, out=args.out), run, args.compare)


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
