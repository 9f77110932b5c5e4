"""`brdfjax plan` replayed on real data (issue 49, part 3).

A real file stands in for the instrument: the planner may choose only geometries the file
holds (its *pool*), and a reading is the file's value at that geometry. The errors are on
readings the planner never saw (its *test*): NIST's PTFE at 532 nm (pool the regular grid,
test the random set, and the other way round) and every RT-300S run in the plane of
incidence (50 deg held out, pool the other incidences).

At equal readings (rungs: fractions of the pool) four ways to choose them are compared:

- ``planner``: `brdfjax.plan`'s defaults, from nothing (space-filling) to the first rung,
  then batches of integrated-variance (ALC) readings, each planned from everything read so
  far (the model and the process refitted before each batch);
- ``even``: the discrepancy's subsample rule (evenly along each incidence's Z-order curve);
- ``random``: a random subset (seed 0);
- ``full``: the whole pool.

Each set of readings is fitted and the test predicted by the model times its learned
discrepancy, as ``brdfjax fit --predict`` predicts: the point prediction of
`brdfjax.predict` (checked equal on one set), without the conformal cross-validation, which
sets the intervals and not the prediction. The ladder uses ggx; the target rung (1/5 of the
pool on RT-300S, 1/10 on PTFE) and the full scan are also scored with ``--model auto`` as
``fit --model auto --predict`` chooses (`brdfjax.instrument.design.auto_model`) where that
runs in reasonable time (not on the random PTFE set, whose every reading has its own
incidence). Instrument time: each batch's route (`brdfjax.instrument.design.route`, motor
travel from the home position) plus the sample changer, summed over the batches.

Nothing was tuned on these sets: the rungs, the start and the batch size were fixed before
the first run. Were they tuned, ``DECIDE`` names the sets to tune on and the rest confirm.

    python benchmarks/bench_plan.py            # every set (~20 min on 2 loaded cores)
    python benchmarks/bench_plan.py --quick    # two sets, printed, BENCHMARKS.md left alone
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks import report
from benchmarks.report import real_data, write_section

HELD_OUT = 50.0  # deg: the RT-300S incidence predicted
RUNGS = {"rt300s": (1 / 10, 1 / 5, 1 / 3), "ptfe": (1 / 40, 1 / 20, 1 / 10)}
TARGET = {"rt300s": 1 / 5, "ptfe": 1 / 10}  # the issue's: readings to reach full scan's error
BATCHES = 5  # ALC batches between rungs (at least 1 reading each)
STRATEGIES = ("planner", "even", "random")
DECIDE = ("NIST PTFE, grid -> random", "NiTE_on_steel_v1o0A")
SLOW_AUTO = ("NIST PTFE, random -> grid",)


def replay_sets(quick: bool) -> list[dict]:
    """Every set: ``{"name", "kind", "pool", "test"}`` (`Measurements`)."""
    import brdfjax

    ptfe = real_data("nist-germer-ptfe")
    grid, scattered = (brdfjax.load(ptfe / name, wavelength_nm=532)
                       for name in ("PTFE.data.csv", "PTFE.data.random.csv"))
    sets = [{"name": "NIST PTFE, grid -> random", "kind": "ptfe", "pool": grid,
             "test": scattered},
            {"name": "NIST PTFE, random -> grid", "kind": "ptfe", "pool": scattered,
             "test": grid}]
    rt300s = real_data("uaz-loft-rt300s")
    runs = sorted((rt300s / "raw").glob("*_v1o0*.xls")) + sorted(
        (rt300s / "raw_legacy_1deg").glob("0*.xls"))
    for path in runs:
        data = brdfjax.load(path, in_plane=True)
        held = data.incidence_mask([HELD_OUT])
        sets.append({"name": path.stem.removesuffix("_20250915").removesuffix("_20250916")
                     .removesuffix("_20251115"), "kind": "rt300s",
                     "pool": data.select(~held), "test": data.select(held)})
    return [sets[0], sets[7]] if quick else sets


def ladder(pool_size: int, kind: str) -> list[int]:
    """The rungs' reading counts."""
    return [max(6, round(f * pool_size)) for f in RUNGS[kind]]


def key_index(pool) -> dict:
    """Pool position of every geometry (`brdfjax.instrument.design._keys`)."""
    from brdfjax.instrument.design import _keys

    return {tuple(row): k for k, row in enumerate(_keys(pool))}


def positions(chosen, index: dict) -> list[int]:
    """Pool positions of a `brdfjax.instrument.design.Plan`'s geometries, in its order."""
    from brdfjax.instrument.design import _keys

    return [index[tuple(row)] for row in _keys(chosen.geometry())]


def planner_batches(pool, rungs: list[int]) -> dict[int, list[list[int]]]:
    """The planner's batches (pool positions) up to each rung: a space-filling start of the
    first rung, then `BATCHES` ALC batches to each next rung."""
    from brdfjax.instrument.design import plan

    index = key_index(pool)
    batches = [positions(plan(None, pool, rungs[0], seed=0), index)]
    out = {rungs[0]: list(batches)}
    for low, high in itertools.pairwise(rungs):
        sizes = np.diff(np.linspace(low, high, BATCHES + 1).round().astype(int))
        for size in sizes[sizes > 0]:
            read = pool.select(np.isin(np.arange(len(pool)), np.concatenate(batches)))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                batches.append(positions(plan(read, pool, int(size), seed=0), index))
        out[high] = list(batches)
    return out


def one_batch(pool, strategy: str, count: int) -> list[list[int]]:
    """The even spread's, the random subset's or the full scan's readings, one batch."""
    from brdfjax.prediction.discrepancy import subsample

    if strategy == "even":
        return [list(subsample(pool.theta_i, pool.theta_r, pool.phi_r, count))]
    if strategy == "random":
        return [list(np.random.default_rng(0).choice(len(pool), count, replace=False))]
    return [list(range(len(pool)))]


def minutes(pool, batches) -> tuple[float, float]:
    """Instrument minutes of ``batches`` (each routed from home, plus the changer) and the
    ratio of their motor time to the same batches in sweep order."""
    from brdfjax.instrument.design import route
    from brdfjax.instrument.simulator import CHANGER_SECONDS

    motor = sweep = 0.0
    for batch in batches:
        angles = np.degrees([pool.theta_i[batch], pool.theta_r[batch], pool.phi_r[batch]])
        _, seconds, sweep_seconds = route(*angles)
        motor, sweep = motor + seconds, sweep + sweep_seconds
    readings = sum(len(b) for b in batches)
    return (motor + CHANGER_SECONDS * readings) / 60, motor / sweep


def predicted(train, test, model: str) -> np.ndarray:
    """The test's BRDF as ``fit --predict`` predicts it: the model fitted to ``train`` times
    its learned discrepancy fitted to every training point (`brdfjax.predict`'s point
    prediction, without the cross-validation that only sets the intervals)."""
    import brdfjax
    from brdfjax.fitting.objective import brdf_values, prepare
    from brdfjax.prediction.intervals import _fit_processes

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = brdfjax.fit(train, model=model, seed=0)
    fitted = np.asarray(brdf_values(result.vector, prepare(train, result.model), result.model))
    (process,) = _fit_processes(train, [fitted], [np.ones(len(train), bool)])
    values = np.asarray(brdf_values(result.vector, prepare(test, result.model), result.model))
    mu, _ = process.predict(test.theta_i, test.theta_r, test.phi_r)
    return process.correct(values, mu)


def errors(train, test, model: str) -> tuple[float, float, str]:
    """Median and 95th percentile relative error on ``test`` (%), and the model used
    (``auto``: `brdfjax.instrument.design.auto_model` of ``train``)."""
    from brdfjax.instrument.design import auto_model

    if model == "auto":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = auto_model(train, seed=0)
    relative = np.abs(predicted(train, test, model) - test.brdf) / np.abs(test.brdf)
    return (100 * float(np.median(relative)), 100 * float(np.percentile(relative, 95)), model)


def check_prediction(train, test) -> float:
    """Largest relative difference between `predicted` and `brdfjax.predict`'s BRDF."""
    import brdfjax

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reference = brdfjax.predict(brdfjax.fit(train, model="ggx", seed=0), test).brdf
    return float(np.max(np.abs(predicted(train, test, "ggx") - reference)
                        / np.abs(reference)))


def replay(case: dict, auto: bool) -> list[dict]:
    """Every strategy at every rung of one set, and the full scan: rows of the table."""
    pool = case["pool"]
    rungs = ladder(len(pool), case["kind"])
    target = max(6, round(TARGET[case["kind"]] * len(pool)))
    started = time.perf_counter()
    planned = planner_batches(pool, rungs)
    plan_seconds = time.perf_counter() - started
    rows = []
    for count in rungs:
        for strategy in STRATEGIES:
            batches = planned[count] if strategy == "planner" else one_batch(pool, strategy,
                                                                             count)
            rows.append(score(case, strategy, batches, auto and count == target))
    rows.append(score(case, "full", one_batch(pool, "full", len(pool)), auto))
    rows[0]["plan_seconds"] = plan_seconds
    return rows


def score(case: dict, strategy: str, batches, auto: bool) -> dict:
    """One row: readings, minutes, route ratio, ggx errors (and auto's)."""
    pool, test = case["pool"], case["test"]
    chosen = np.concatenate(batches)
    train = pool.select(np.isin(np.arange(len(pool)), chosen))
    row = {"set": case["name"], "strategy": strategy, "readings": int(chosen.size),
           "fraction": chosen.size / len(pool)}
    row["minutes"], row["route_ratio"] = minutes(pool, batches)
    row["ggx"] = errors(train, test, "ggx")
    if auto:
        row["auto"] = errors(train, test, "auto")
    print(f"  {strategy:8s} {row['readings']:5d} readings {row['minutes']:7.1f} min  "
          f"ggx {row['ggx'][0]:.2f} / {row['ggx'][1]:.2f} %"
          + (f"  auto ({row['auto'][2]}) {row['auto'][0]:.2f} / {row['auto'][1]:.2f} %"
             if auto else ""), flush=True)
    return row


def planning_speed(repeats: int = 5) -> list[float]:
    """Warm seconds of `brdfjax.plan` choosing 20 readings from 300 measured among 5,000
    candidates (issue 49's speed target): 300 of the PTFE grid (a new draw each call), the
    candidates the grid, the random set and reachable geometries drawn uniformly (seed 0);
    the first call (compilation) left out."""
    import brdfjax
    from brdfjax.data.measurements import Measurements
    from brdfjax.instrument.plan import unreachable

    ptfe = real_data("nist-germer-ptfe")
    grid, scattered = (brdfjax.load(ptfe / name, wavelength_nm=532)
                       for name in ("PTFE.data.csv", "PTFE.data.random.csv"))
    rng = np.random.default_rng(0)
    drawn = rng.uniform([0, 0, 0], [75, 85, 360], (3000, 3))
    drawn = drawn[[unreachable(*g) is None for g in drawn]]
    angles = np.vstack([np.degrees([d.theta_i, d.theta_r, d.phi_r]).T for d in (grid, scattered)]
                       + [drawn])[:5000].T
    candidates = Measurements.from_degrees(*angles, np.full(angles.shape[1], np.nan))
    seconds = []
    for k in range(repeats + 1):
        measured = grid.select(np.isin(np.arange(len(grid)), np.random.default_rng(100 + k)
                                       .choice(len(grid), 300, replace=False)))
        started = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            brdfjax.plan(measured, candidates, 20, seed=0)
        seconds.append(time.perf_counter() - started)
    return seconds[1:]


def at(rows: list[dict], case: str, strategy: str, readings: int | None = None) -> dict:
    """The row of ``case`` and ``strategy`` (at ``readings``; the full scan's without)."""
    return next(r for r in rows if r["set"] == case and r["strategy"] == strategy
                and (readings is None or r["readings"] == readings))


def verdicts(rows: list[dict], case: str, kind: str) -> dict:
    """The issue's targets on one set: the planner at the target rung within 1.2x of the
    full scan (median and 95th percentile; ggx, and auto where scored), its 95th percentile
    within 1.05x of the even spread's at every rung, its route within 1.2x of sweep order."""
    full = at(rows, case, "full")
    target = max(6, round(TARGET[kind] * len(next(c for c in CASES if c["name"] == case)
                                              ["pool"])))
    planner = at(rows, case, "planner", target)

    def within(model):
        if model not in planner or model not in full:
            return None
        return all(planner[model][k] <= 1.2 * full[model][k] for k in (0, 1))

    rungs = [r["readings"] for r in rows if r["set"] == case and r["strategy"] == "planner"]
    even = all(at(rows, case, "planner", n)["ggx"][1] <= 1.05 * at(rows, case, "even", n)["ggx"][1]
               for n in rungs)
    route = max(r["route_ratio"] for r in rows if r["set"] == case and r["strategy"] == "planner")
    return {"target": target, "ggx": within("ggx"), "auto": within("auto"), "even": even,
            "route": route}


def mark(value) -> str:
    return "-" if value is None else ("yes" if value else "**no**")


def cells(row: dict, model: str = "ggx") -> str:
    return "-" if model not in row else f"{row[model][0]:.2f} / {row[model][1]:.2f}"


def table(rows: list[dict]) -> list[str]:
    """One line per set at its target rung."""
    lines = [("| set | pool | readings (target) | planner | even | random | full scan | "
              "auto: planner / full (model) | minutes: planner / even / full | planner <= "
              "1.2x full (ggx; auto) | 95th <= 1.05x even, every rung | route / sweep |"),
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for case in CASES:
        name, kind = case["name"], case["kind"]
        verdict = verdicts(rows, name, kind)
        n = verdict["target"]
        planner, even, random = (at(rows, name, s, n) for s in STRATEGIES)
        full = at(rows, name, "full")
        auto = (f"{cells(planner, 'auto')} ({planner['auto'][2]}); full {cells(full, 'auto')} "
                f"({full['auto'][2]})" if "auto" in planner else "-")
        lines.append(
            f"| {name}{' (decide)' if name in DECIDE else ''} | {len(case['pool'])} | {n} | "
            f"{cells(planner)} | {cells(even)} | {cells(random)} | {cells(full)} | {auto} | "
            f"{planner['minutes']:.1f} / {even['minutes']:.1f} / {full['minutes']:.1f} | "
            f"{mark(verdict['ggx'])}; {mark(verdict['auto'])} | {mark(verdict['even'])} | "
            f"{verdict['route']:.2f} |")
    return lines


def ladder_table(rows: list[dict]) -> list[str]:
    """Every rung of the PTFE sets, and the RT-300S runs' median ratio to the full scan."""
    lines = [("| set | readings (fraction) | planner | even | random | minutes: planner / "
              "even / random |"), "|---|---|---|---|---|---|"]
    for case in CASES:
        if case["kind"] != "ptfe":
            continue
        for n in sorted({r["readings"] for r in rows if r["set"] == case["name"]
                         and r["strategy"] == "planner"}):
            picked = [at(rows, case["name"], s, n) for s in STRATEGIES]
            lines.append(f"| {case['name']} | {n} ({picked[0]['fraction']:.3f}) | "
                         + " | ".join(cells(r) for r in picked) + " | "
                         + " / ".join(f"{r['minutes']:.1f}" for r in picked) + " |")
    for k, fraction in enumerate(RUNGS["rt300s"]):
        ratios = {s: [] for s in STRATEGIES}
        for case in (c for c in CASES if c["kind"] == "rt300s"):
            n = ladder(len(case["pool"]), "rt300s")[k]
            full = at(rows, case["name"], "full")["ggx"]
            for s in STRATEGIES:
                got = at(rows, case["name"], s, n)["ggx"]
                ratios[s].append((got[0] / full[0], got[1] / full[1]))
        lines.append(f"| RT-300S, 14 runs: median of error / full scan's | {fraction:.3f} | "
                     + " | ".join("{:.2f}x / {:.2f}x".format(*np.median(ratios[s], axis=0))
                                  for s in STRATEGIES) + " | - |")
    return lines


def figure(rows: list[dict], path: Path) -> None:
    """Error against readings: median (top) and 95th percentile (bottom), each PTFE set and
    the RT-300S runs' median ratio to the full scan."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [c["name"] for c in CASES if c["kind"] == "ptfe"] + ["RT-300S (14 runs)"]
    fig, axes = plt.subplots(2, len(panels), figsize=(4.2 * len(panels), 6.5), squeeze=False)
    for column, panel in enumerate(panels):
        for strategy, style in zip(STRATEGIES, ("o-", "s--", "^:")):
            x, y = _curve(rows, panel, strategy)
            for k in (0, 1):
                axes[k, column].plot(x, y[:, k], style, label=strategy)
        for k, what in enumerate(("median", "95th percentile")):
            ax = axes[k, column]
            if panel.startswith("RT"):
                ax.axhline(1.0, color="k", lw=0.8, label="full scan")
                ax.axhline(1.2, color="grey", lw=0.8, ls="--", label="1.2x full scan")
                ax.set_ylabel(f"{what} error / full scan's (median)")
            else:
                full = at(rows, panel, "full")["ggx"][k]
                ax.axhline(full, color="k", lw=0.8, label="full scan")
                ax.axhline(1.2 * full, color="grey", lw=0.8, ls="--", label="1.2x full scan")
                ax.set_ylabel(f"{what} relative error (%)")
            ax.set_xlabel("readings / pool")
            ax.set_title(panel, fontsize=9)
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("brdfjax plan replayed on real data: held-out error against readings (ggx)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _curve(rows, panel, strategy):
    """(fractions, (median, 95th)) of one strategy on a PTFE set, or the RT-300S runs'
    median ratios to the full scan."""
    if not panel.startswith("RT"):
        mine = sorted((r for r in rows if r["set"] == panel and r["strategy"] == strategy),
                      key=lambda r: r["readings"])
        return [r["fraction"] for r in mine], np.array([r["ggx"][:2] for r in mine])
    x, y = [], []
    for k, fraction in enumerate(RUNGS["rt300s"]):
        ratios = []
        for case in (c for c in CASES if c["kind"] == "rt300s"):
            got = at(rows, case["name"], strategy, ladder(len(case["pool"]), "rt300s")[k])
            full = at(rows, case["name"], "full")
            ratios.append([got["ggx"][j] / full["ggx"][j] for j in (0, 1)])
        x.append(fraction)
        y.append(np.median(ratios, axis=0))
    return x, np.array(y)


def section(rows: list[dict], check: float, plan_seconds: float, speed: list) -> str:
    rt = [verdicts(rows, c["name"], c["kind"]) for c in CASES]
    lines = [
        "## Planning what to measure, replayed on real data",
        "",
        ("A real file stands in for the instrument: `brdfjax plan` (its defaults: ggx, region "
         "the candidates) may choose only the file's geometries, and a reading is the file's "
         "value there. Errors are relative, on readings it never saw: NIST PTFE at 532 nm "
         "(pool the regular grid, test the random set, and the other way round) and every "
         f"RT-300S run in the plane of incidence ({HELD_OUT:g} deg held out, pool the other "
         "incidences). The planner starts space-filling (greedy maximin) to the first rung, "
         f"then adds {BATCHES} ALC batches per rung, the model and its discrepancy refitted "
         "before each. Even spread: the discrepancy's subsample rule; random: seed 0; full "
         "scan: the whole pool. Each set of readings is fitted and the test predicted as "
         "`fit --predict` predicts (model x learned discrepancy; the point prediction of "
         f"`brdfjax.predict`, equal to it within {check:.1e} on one set, without the "
         "cross-validation that sets only the intervals). The ladder uses ggx; the target "
         "rung and the full scan are also scored with `--model auto` as `fit --model auto "
         "--predict` chooses, except on the random PTFE pool (every reading its own "
         "incidence: the cross-validation over incidences is out of reach there). Minutes: "
         "each batch's route (motor travel from home, `brdfjax.instrument.design.route`) "
         "plus 1 s of sample changer per reading, summed over batches. Nothing was tuned on "
         "these sets (rungs, start and batch size fixed before the first run); the sets "
         "marked (decide) are those any later tuning is to use, the others confirm."),
        "",
        ("Targets (issue 49): the planner at 1/5 of the readings on every RT-300S run and 1/10 "
         "on PTFE within 1.2x of the full scan's median and 95th percentile error; its 95th "
         "percentile within 1.05x of the even spread's at equal readings on every set; its "
         "route at most 1.2x the sweep order's."),
        "",
        "Median / 95th percentile relative error (%) at the target rung:",
        "",
        *table(rows),
        "",
        "Every rung (median / 95th percentile %, ggx):",
        "",
        *ladder_table(rows),
        "",
        (f"Met: planner within 1.2x of the full scan (ggx) on "
         f"{sum(bool(v['ggx']) for v in rt)}/{len(rt)} sets; with auto on "
         f"{sum(bool(v['auto']) for v in rt)}/{sum(v['auto'] is not None for v in rt)}; "
         f"95th percentile within 1.05x of the even spread at every rung on "
         f"{sum(v['even'] for v in rt)}/{len(rt)}; route / sweep at most "
         f"{max(v['route'] for v in rt):.2f}. Planning time, all batches of all sets: "
         f"{plan_seconds:.0f} s."),
        "",
        (f"Speed (target: at most 2 s warm): planning 20 readings from 300 measured among "
         f"5,000 candidates took a median {np.median(speed):.2f} s warm "
         f"({min(speed):.2f}-{max(speed):.2f} s, {len(speed)} calls, each from another 300 "
         "of the PTFE grid; `planning_speed`)."),
        "",
        "![error against readings](benchmarks/plan.png)",
    ]
    return "\n".join(lines)


CASES: list[dict] = []
ROWS_FILE = Path(tempfile.gettempdir()) / "bench_plan_rows.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="two sets, printed; BENCHMARKS.md and the plot left alone")
    parser.add_argument("--rows", metavar="JSON",
                        help="write the table and plot from a run's rows (saved to "
                             "ROWS_FILE by every run) instead of replaying; the speed is "
                             "measured anew")
    args = parser.parse_args()
    report.DRY_RUN = args.quick
    import brdfjax
    from brdfjax.instrument.design import one_blas_thread

    brdfjax.cache.enable()
    CASES.extend(replay_sets(args.quick))
    if args.rows:
        saved = json.loads(Path(args.rows).read_text())
        return report_rows(saved["rows"], saved["check"], args.quick)
    rows = []
    with one_blas_thread():  # as plan runs; the results do not depend on it
        first = CASES[-1]
        check = check_prediction(first["pool"], first["test"])
        print(f"point prediction against brdfjax.predict: {check:.2e}", flush=True)
        for case in CASES:
            print(f"{case['name']}: pool {len(case['pool'])}, test {len(case['test'])}",
                  flush=True)
            rows += replay(case, auto=case["name"] not in SLOW_AUTO)
            ROWS_FILE.write_text(json.dumps({"rows": rows, "check": check}))
    report_rows(rows, check, args.quick)


def report_rows(rows: list[dict], check: float, quick: bool) -> None:
    """The plot (not with ``quick``) and the section."""
    plan_seconds = sum(r.get("plan_seconds", 0.0) for r in rows)
    if not quick:
        figure(rows, REPO / "benchmarks" / "plan.png")
    speed = planning_speed()
    print(f"planning speed: {speed}", flush=True)
    write_section("plan-replay", section(rows, check, plan_seconds, speed))


if __name__ == "__main__":
    main()
