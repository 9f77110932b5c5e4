"""A cube of many 64-point samples through ``brdfjax batch CUBE.h5``; the vmap lane proxy.

    python benchmarks/bench_cube.py --count 100000     # section cube of BENCHMARKS.md
    python benchmarks/bench_cube.py --only lanes       # section lanes-cpu
    python benchmarks/bench_cube.py --quick            # 1024 samples, nothing written
    python benchmarks/bench_cube.py --only ross-li --baseline ../before   # ross-li-batch

Samples: the paper's five samples in turn, each parameter scaled by ``exp(0.1 N(0, 1))``, on
one shared 64-point in-plane geometry (incidences 10/30/45/60 deg, 16 angles each), 2.5 %
relative noise; the five-parameter model with `brdfjax.fit`'s default search. The cube is
fitted by the CLI as a user runs it, in a fresh process whose compilation cache is already
warm (a first run on a small cube of the same shapes fills it; its time is reported
apart). Peak memory is the process's ``ru_maxrss``. A subset of samples is fitted one by one
with `brdfjax.fit` (same seed) and their E compared. The same cube is then fitted again,
killed with SIGKILL when about half of it is journalled, resumed, and compared with the
uninterrupted results.

``ross-li``: 10,000 MODIS-like pixels (16 readings: sun at 30 and 50 deg, views at 0-60 deg
on two relative azimuths; Ross-Li weights drawn at random, 2 % noise), on one shared
geometry and with each pixel's angles moved a little (per-sample geometry), fitted with
``--model ross-li``: the warm command (the second run of each cube: caches filled) and
`brdfjax.fit_batch` in a warm process, for this checkout and a ``--baseline`` checkout
(the code before a change), beside NumPy/SciPy per-pixel least squares of the same kernels.

``lanes``: the CPU stand-in for the accelerator design (device-aware lanes). Under ``vmap``
a chunk runs as many loop iterations as its slowest lane: from the LM steps of each sample
(per-sample path), how many iterations a chunk of 64 vmapped samples would run, and with
the slow lanes moved to a second batch; and the measured time of the vmapped strategies.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks.report import child_env, commit_of, worker_json, write_section

CLI = [sys.executable, "-m", "brdfjax.cli", "batch"]


def make_cube(path, count: int, seed: int = 0) -> None:
    """The synthetic cube of the module docstring."""
    import jax

    from brdfjax.data.formats.cube import write_cube
    from brdfjax.models.paper import PAPER_SAMPLES, brdf

    rng = np.random.default_rng(seed)
    theta_i = np.repeat([10.0, 30.0, 45.0, 60.0], 16)
    signed = np.tile(np.linspace(-70, 70, 16), 4)
    theta_r, phi_r = np.abs(signed), np.where(signed < 0, 180.0, 0.0)
    base = np.array(list(PAPER_SAMPLES.values()))
    params = base[np.arange(count) % len(base)] * np.exp(0.1 * rng.standard_normal((count, 5)))
    angles = np.radians([theta_i, theta_r, phi_r])
    values = np.asarray(jax.jit(jax.vmap(lambda p: brdf(p, *angles)))(params))
    values = values * (1 + 0.025 * rng.standard_normal(values.shape))
    write_cube(path, theta_i, theta_r, phi_r, values, sample=[f"px{k}" for k in range(count)])


def run(cube, out, env, extra=()) -> dict:
    """One ``brdfjax batch`` of the cube in a fresh process: wall, CPU, peak memory (that
    process's own, from ``wait4``: ``RUSAGE_CHILDREN`` would keep the largest of every
    earlier child, the compiling warm-up run's included)."""
    with tempfile.TemporaryFile("w+") as stderr:
        tic = time.perf_counter()
        # Run beside the results: ``python -m`` puts the working directory first on the
        # path, and a checkout there would shadow the one in env's PYTHONPATH.
        process = subprocess.Popen([*CLI, str(cube), "--out", str(out), *extra], env=env,
                                   stdout=subprocess.DEVNULL, stderr=stderr, text=True,
                                   cwd=Path(out).parent)
        _, status, usage = os.wait4(process.pid, 0)
        wall = time.perf_counter() - tic
        process.returncode = os.waitstatus_to_exitcode(status)
        stderr.seek(0)
        said = stderr.read()
    if process.returncode not in (0, 1):
        raise RuntimeError(said)
    return {"wall": wall, "cpu": usage.ru_utime + usage.ru_stime,
            "peak_mb": usage.ru_maxrss / 1024, "stderr": said}


def read(path) -> dict:
    import h5py

    with h5py.File(path, "r") as results:
        return {name: results[name][...] for name in results}


def kill_and_resume(cube, out, env, count: int, chunk: int) -> tuple[int, dict]:
    """Kill a run with SIGKILL at about half its chunks, resume it: samples kept, the rerun."""
    parts = Path(f"{out}.parts")
    process = subprocess.Popen([*CLI, str(cube), "--out", str(out)], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    half = count // chunk // 2
    while process.poll() is None and len(list(parts.glob("*.npz"))) < half:
        time.sleep(0.01)
    process.send_signal(signal.SIGKILL)
    process.wait()
    kept = sum(len(np.load(p)["index"]) for p in parts.glob("*.npz"))
    resumed = run(cube, out, env)
    return kept, resumed


def bench_cube(count: int, subset: int, quick: bool) -> None:
    from brdfjax.data.formats.cube import Cube
    from brdfjax.fitting.fit import fit

    folder = Path(tempfile.mkdtemp(prefix="brdfjax-cube-"))
    env = child_env(BRDFJAX_CACHE=str(folder / "cache"), PYTHONPATH=str(REPO))
    from brdfjax.commands.batch import CUBE_CHUNK as chunk  # the default --chunk-size
    make_cube(folder / "warm.h5", 2 * chunk, seed=1)
    first = run(folder / "warm.h5", folder / "warm_results.h5", env)
    tic = time.perf_counter()
    make_cube(folder / "cube.h5", count)
    made = time.perf_counter() - tic
    timed = run(folder / "cube.h5", folder / "results.h5", env)
    results = read(folder / "results.h5")
    status = results["status"].astype(str)
    with Cube(folder / "cube.h5") as cube:
        picks = np.linspace(0, count - 1, subset).astype(int)
        singles = [fit(data) for data in cube.read(picks)]
    relative = [abs(results["error"][k] - s.error) / s.error for k, s in zip(picks, singles)]
    kept, resumed = kill_and_resume(folder / "cube.h5", folder / "again.h5", env, count, chunk)
    again = read(folder / "again.h5")
    same = again.keys() == results.keys() and all(
        np.array_equal(again[name], results[name], equal_nan=results[name].dtype.kind == "f")
        for name in results)
    per_sample = timed["wall"] / count
    text = (
        f"## A cube of many samples: `brdfjax batch CUBE.h5`\n\n"
        f"Target: 100,000 samples of 64 points (shared geometry, the five-parameter model, "
        f"default search) in at most 5 minutes on 2 cores (3 ms per sample), peak memory at "
        f"most 2 GB, every sample's E within 1e-6 of its single fit; killed halfway and "
        f"resumed with nothing lost or duplicated.\n\n"
        f"| samples | wall (s) | ms per sample | CPU (s) | peak memory (MB) |\n"
        f"|---|---|---|---|---|\n"
        f"| {count} | {timed['wall']:.1f} | {1000 * per_sample:.2f} | {timed['cpu']:.1f} | "
        f"{timed['peak_mb']:.0f} |\n\n"
        f"- Warm compilation cache (a first run of {2 * chunk} samples of the same shapes, "
        f"compilation included, took {first['wall']:.1f} s); making the cube took "
        f"{made:.1f} s. Statuses: {int(np.sum(status == 'converged'))} converged, "
        f"{int(np.sum(status == 'max_steps'))} at the step cap, "
        f"{int(np.sum(status == 'failed'))} failed.\n"
        f"- At this rate 100,000 samples take {per_sample * 1e5 / 60:.1f} min: "
        f"target of 5 min **{'met' if per_sample * 1e5 <= 300 else 'not met'}**"
        + (" (extrapolated from the measured count)" if count < 100_000 else "") + ".\n"
        f"- E against `brdfjax.fit` of {subset} samples spread over the cube (same seed): "
        f"largest relative difference {max(relative):.1e}.\n"
        f"- Killed with SIGKILL after {kept} samples were journalled, then resumed "
        f"({resumed['wall']:.1f} s): results identical to the uninterrupted run's, dataset "
        f"by dataset: {'yes' if same else 'NO'}.\n")
    if quick:
        print(text)
    else:
        write_section("cube", text)


def bench_lanes(quick: bool) -> None:
    """The per-sample path's LM steps, and the iterations a vmapped chunk would run."""
    worker = subprocess.run([sys.executable, __file__, "--lanes-worker",
                             str(256 if quick else 1024)], capture_output=True, text=True,
                            check=False, env=child_env(PYTHONPATH=str(REPO)))
    if worker.returncode:
        raise RuntimeError(worker.stderr)
    r = json.loads(worker.stdout.strip().splitlines()[-1])
    rows = "\n".join(f"| {k} | {v['wall']:.2f} | {v['cpu']:.2f} | {v['difference']:.1e} |"
                     for k, v in r["strategies"].items())
    text = (
        "## Device-aware lanes: the CPU stand-in (no accelerator lent)\n\n"
        "Under `vmap` a loop runs as many iterations as its slowest lane. The LM steps of "
        f"each of {r['count']} cube samples (64 points, per-sample path; a sample's longest "
        "start), and the loop iterations each design runs:\n\n"
        f"- longest LM start per sample: median {r['median']:.0f}, 90th percentile "
        f"{r['p90']:.0f}, max {r['max']} steps;\n"
        f"- per-sample path (today's `lax.map`): {r['sequential']} LM iterations, one "
        "after another;\n"
        f"- chunks of 64 samples side by side: {r['vmapped']} iterations (the slowest lane "
        f"of each chunk), {r['sequential'] / r['vmapped']:.0f}x fewer, but "
        f"{64 * r['vmapped']} lane-steps, {64 * r['vmapped'] / r['sequential']:.1f}x the "
        "per-sample work: on a CPU, where a lane costs as much as a sample, vmapping loses; "
        "on an accelerator, where lanes run at once, it wins;\n"
        f"- slow lanes (above twice their chunk's median) moved to a second batch: "
        f"{r['slow']} lanes, {r['split']} iterations in all.\n\n"
        "Measured, 256 samples, 2 CPU devices (`search_batch`, `polish_batch` of the map "
        "path, and `lanes='vmap'`: every sample and each of its LM starts side by side, "
        "the convergence round stopped at `LANE_STEPS` and the starts still running "
        "resumed in a second batch, `brdfjax.fitting.batch`; E against the per-sample "
        "path):\n\n"
        "| design | wall (s) | CPU (s) | largest relative difference in E |\n"
        "|---|---|---|---|\n" + rows + "\n\n"
        + ("Every strategy gave the per-sample path's E to 1e-9 on these samples. "
           if all(v["difference"] <= 1e-9 for v in r["strategies"].values()) else
           "Not every strategy gave the per-sample path's E to 1e-9 on these samples. ")
        + "A vmapped genetic search computes in another order (last bits differ), and a "
        "search that branches on them can end in another basin: on another cube of the same "
        "kind (256 samples, measured by hand on 2026-12-01 before this script existed, load "
        "about 9), `None, None` differed from the per-sample path by 3.5e-4 in E on at "
        "least one sample while `1, None` (LM vmapped, search mapped) stayed within "
        "7.4e-15. The equality must be tested per sample, not assumed. On a CPU, "
        "`lanes='vmap'` (the accelerator's design, the starts side by side too) costs "
        "what its lane-steps cost: it is the default only where lanes run at once.\n")
    if quick:
        print(text)
    else:
        write_section("lanes-cpu", text)


def lanes_worker(count: int) -> None:
    from brdfjax.fitting.batch import fit_batch, use_every_core

    use_every_core()
    from brdfjax.cache import enable

    folder = Path(tempfile.mkdtemp(prefix="brdfjax-lanes-"))
    enable(folder / "cache")
    make_cube(folder / "cube.h5", count)
    from brdfjax.data.formats.cube import Cube

    with Cube(folder / "cube.h5") as cube:
        samples = cube.read(np.arange(count))
    base = fit_batch(samples, chunk_size=64)
    longest = np.array([r.lm_steps.max() for r in base])
    blocks = longest.reshape(-1, 64)
    cut = 2 * np.median(blocks, axis=1, keepdims=True)
    slow = np.sort(blocks[blocks > cut])[::-1]
    split = int(np.where(blocks <= cut, blocks, 0).max(1).sum() + slow[::64].sum())
    strategies = {}
    reference = np.array([r.error for r in base[:256]])
    designs = {f"{search}, {polish}": {"search_batch": search, "polish_batch": polish}
               for search, polish in ((1, 1), (1, None), (None, None))}
    designs["lanes='vmap'"] = {"lanes": "vmap"}  # the accelerator's: starts side by side too
    for label, design in designs.items():
        fit_batch(samples[:64], chunk_size=64, **design)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        tic = time.perf_counter()
        results = fit_batch(samples[:256], chunk_size=64, **design)
        wall = time.perf_counter() - tic
        after = resource.getrusage(resource.RUSAGE_SELF)
        errors = np.array([r.error for r in results])
        strategies[label] = {
            "wall": wall, "cpu": after.ru_utime + after.ru_stime - usage.ru_utime
            - usage.ru_stime, "difference": float(np.max(np.abs(errors - reference)
                                                         / reference))}
    print(json.dumps({"count": count, "median": float(np.median(longest)),
                      "p90": float(np.percentile(longest, 90)), "max": int(longest.max()),
                      "sequential": int(longest.sum()), "vmapped": int(blocks.max(1).sum()),
                      "slow": int(slow.size), "split": split, "strategies": strategies}))


def make_modis_cube(path, count: int, own_geometry: bool, seed: int = 0) -> None:
    """The MODIS-like Ross-Li cube of the module docstring."""
    from brdfjax.data.formats.cube import write_cube
    from brdfjax.models.ross_li import kernels

    rng = np.random.default_rng(seed)
    angles = [a.ravel() for a in np.meshgrid([30.0, 50.0], [0.0, 20.0, 40.0, 60.0],
                                             [30.0, 150.0], indexing="ij")]
    if own_geometry:
        angles = [a + rng.uniform(0, 3, (count, a.size)) for a in angles]
    weights = np.stack([rng.uniform(0.15, 0.4, count), rng.uniform(0, 0.15, count),
                        rng.uniform(0, 0.04, count)], axis=1)
    volume, geometric, _ = kernels(*np.radians(np.broadcast_arrays(*angles)))
    clean = (weights[:, :1] + weights[:, 1:2] * np.asarray(volume)
             + weights[:, 2:] * np.asarray(geometric)) / np.pi
    write_cube(path, *angles, clean * (1 + 0.02 * rng.standard_normal(clean.shape)))


def bench_rossli(count: int, baseline: Path | None, quick: bool) -> None:
    from brdfjax.commands.batch import CUBE_CHUNK

    folder = Path(tempfile.mkdtemp(prefix="brdfjax-rossli-"))
    trees = {"after": REPO} | ({"before": baseline.resolve()} if baseline else {})
    rows, peers = [], {}
    for geometry in ("shared", "per-sample"):
        cube = folder / f"{geometry}.h5"
        make_modis_cube(cube, count, own_geometry=geometry == "per-sample")
        for label, tree in trees.items():
            env = child_env(BRDFJAX_CACHE=str(folder / "cache"), PYTHONPATH=str(tree))
            out = folder / f"{geometry}-{label}.h5"
            command = [run(cube, out, env, ("--model", "ross-li"))]  # fills the caches
            for _ in range(2):
                os.remove(out)
                command.append(run(cube, out, env, ("--model", "ross-li")))
            worker = worker_json([sys.executable, __file__, "--rossli-worker", str(cube),
                                  str(tree)], env)
            rows.append((geometry, label, [r["wall"] for r in command[1:]], worker))
            peers[geometry] = worker["peers"]
    if baseline:
        compared = {g: (read(folder / f"{g}-before.h5"), read(folder / f"{g}-after.h5"))
                    for g in ("shared", "per-sample")}
        same = {g: all(np.array_equal(b[n], a[n]) for n in ("f_iso", "f_vol", "f_geo",
                                                              "error", "status"))
                for g, (b, a) in compared.items()}
        apart = {g: {n: float(np.max(np.abs(a[n] - b[n]) / np.where(b[n] == 0, 1, abs(b[n]))))
                     for n in ("error", "f_iso", "f_vol", "f_geo")}
                 for g, (b, a) in compared.items()}
    def shown(walls):
        return " / ".join(f"{w:.2f}" for w in walls) if walls else "-"

    table = "\n".join(
        f"| {geometry} | {label} | {shown(walls)} | {shown(worker['fit_batch'])} | "
        f"{shown(worker.get('table'))} |" for geometry, label, walls, worker in rows)
    started = start_up()
    peer_rows = "\n".join(
        f"| {geometry} | {name} | {peer['seconds']:.2f} | {peer['difference']:.1e} |"
        for geometry, found in peers.items() for name, peer in found.items())
    best = min(min(walls) for geometry, label, walls, _ in rows
               if label == "after" and geometry == "shared")
    text = (
        "## Ross-Li per pixel: `brdfjax batch CUBE.h5 --model ross-li`\n\n"
        f"Target: {count} small samples in at most 2 s warm (Ross-Li is linear: each fit is "
        "one exact solve). The cube: MODIS-like pixels of 16 readings (sun at 30 and 50 deg, "
        "views 0-60 deg on relative azimuths 30 and 150 deg), Ross-Li weights drawn at "
        "random, 2 % noise; one geometry shared by every pixel, or each pixel's angles "
        "moved by up to 3 deg (per-sample geometry, (N, P) angles).\n\n"
        "Wall seconds, two runs each: the warm command (a first run filled the caches; "
        "results deleted between runs; process start-up, reading and writing included, "
        f"the default `--chunk-size`, {CUBE_CHUNK} for a cube) and `brdfjax.fit_batch` of "
        "the same samples in a warm process (default `chunk_size` 256, one CPU device per "
        "core), returning a `FitResult` per sample or, with `table=True` (what the command "
        "runs), the numbers of every sample as arrays. *before*: the baseline "
        "checkout" + (f" `{commit_of(baseline)}`" if baseline else "") + "; *after*: this "
        "one" + (f" `{commit_of(REPO)}`" if baseline else "") + ".\n\n"
        "| geometry | code | command (s) | fit_batch (s) | fit_batch, table (s) |\n"
        "|---|---|---|---|---|\n" + table + "\n\n"
        + ("".join(f"- {g} geometry, results before and after: " + (
            "identical (weights, E, status).\n" if same[g] else
            "statuses equal; largest relative difference "
            + ", ".join(f"{n} {v:.1e}" for n, v in apart[g].items())
            + " (rounding: E summed in another order, or solves vectorised over chunks of "
            "other sizes).\n")
            for g in same) if baseline else "")
        + f"- Target of 2 s for the warm command: **{'met' if best <= 2 else 'not met'}** "
        f"(best {best:.2f} s, shared geometry). A process that only imports JAX and h5py "
        f"and starts JAX (`python -c 'import h5py, jax; jax.devices()'`) takes "
        f"{shown(started)} s here, in the same run: that much of every command is "
        "start-up.\n\n"
        "What a user would write instead, in the same process, on the same samples "
        "(the kernels computed once per distinct geometry and not timed, as brdfjax's "
        "geometry is in its times): SciPy's bounded `lsq_linear` per pixel (the same "
        "problem: weights in [0, 10]), NumPy's unconstrained `lstsq` per pixel, and one "
        "batched solve of the normal equations for all pixels. E is compared with "
        "brdfjax's on every pixel for `lsq_linear`, on the pixels with no weight at a "
        "bound for the unconstrained ones:\n\n"
        "| geometry | method | seconds | largest relative difference in E |\n"
        "|---|---|---|---|\n" + peer_rows + "\n")
    if quick:
        print(text)
    else:
        write_section("ross-li-batch", text)


def rossli_worker(path, tree) -> None:
    """``fit_batch`` of the cube in this (warm) process, with the brdfjax of checkout
    ``tree``, then its NumPy/SciPy peers."""
    sys.path.insert(0, tree)
    from brdfjax.fitting.batch import fit_batch, use_every_core

    use_every_core()
    from brdfjax.cache import enable
    from brdfjax.data.formats.cube import Cube

    enable()
    with Cube(path) as cube:
        samples = cube.read(np.arange(cube.count))
    def timed(**options) -> tuple[list, object]:
        times = []
        for _ in range(3):  # the first loads the compiled stages
            tic = time.perf_counter()
            results = fit_batch(samples, model="ross-li", **options)
            times.append(time.perf_counter() - tic)
        return times[1:], results

    times, results = timed()
    # The table (every sample's numbers formed a chunk at once), where the checkout has it.
    table = (timed(table=True)[0] if "table" in inspect.signature(fit_batch).parameters
             else None)
    errors = np.array([r.error for r in results])
    inside = np.array([not r.at_bounds for r in results])
    print(json.dumps({"fit_batch": times, "table": table,
                      "peers": least_squares_peers(samples, errors, inside)}))


def start_up() -> list[float]:
    """Wall seconds of a Python process that only imports what the command needs first
    (JAX, h5py) and starts JAX: the part of the command no batch code can shorten."""
    walls = []
    for _ in range(3):
        tic = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import h5py, jax; jax.devices()"], check=True)
        walls.append(time.perf_counter() - tic)
    return walls


def least_squares_peers(samples, errors, inside) -> dict:
    """Per-pixel least squares of the Ross-Li kernels, timed, E against brdfjax's."""
    from scipy.optimize import lsq_linear

    from brdfjax.models.ross_li import kernels

    def design(data):
        volume, geometric, cos_r = map(np.asarray, kernels(data.theta_i, data.theta_r,
                                                            data.phi_r))
        return np.stack([np.ones_like(volume), volume, geometric], 1) * (cos_r / np.pi)[:, None]

    known = {}
    columns = [known.setdefault(np.stack([d.theta_i, d.theta_r, d.phi_r]).tobytes(),
                                design(d)) for d in samples]
    targets = [d.brdf * np.cos(d.theta_r) for d in samples]

    def error(a, c, y):
        return float(np.sum((a @ c - y) ** 2) / np.sum(y**2))

    def per_pixel(solve):
        tic = time.perf_counter()
        found = [solve(a, y) for a, y in zip(columns, targets)]
        return time.perf_counter() - tic, found

    timed = {"scipy lsq_linear per pixel, bounded": per_pixel(
                 lambda a, y: lsq_linear(a, y, bounds=(0, 10), method="bvls").x),
             "numpy lstsq per pixel": per_pixel(lambda a, y: np.linalg.lstsq(a, y)[0])}
    tic = time.perf_counter()
    a, y = np.stack(columns), np.stack(targets)
    normal = np.linalg.solve(np.einsum("npk,npl->nkl", a, a),
                             np.einsum("npk,np->nk", a, y)[..., None])[..., 0]
    timed["numpy normal equations, all pixels at once"] = (time.perf_counter() - tic, normal)
    peers = {}
    for name, (seconds, found) in timed.items():
        theirs = np.array([error(a, c, y) for a, c, y in zip(columns, found, targets)])
        compared = slice(None) if "bounded" in name else inside
        peers[name] = {"seconds": seconds, "difference": float(np.max(
            np.abs(theirs[compared] - errors[compared]) / errors[compared]))}
    return peers


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=100_000)
    parser.add_argument("--subset", type=int, default=20)
    parser.add_argument("--only", choices=("cube", "lanes", "ross-li"))
    parser.add_argument("--baseline", type=Path,
                        help="ross-li: also time this checkout (the code before a change)")
    parser.add_argument("--rossli-worker", nargs=2, metavar=("CUBE", "TREE"))
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--lanes-worker", type=int)
    args = parser.parse_args()
    if args.lanes_worker:
        return lanes_worker(args.lanes_worker)
    if args.rossli_worker:
        return rossli_worker(*args.rossli_worker)
    if args.quick:
        from benchmarks import report

        report.DRY_RUN = True
    if args.only in (None, "cube"):
        bench_cube(1024 if args.quick else args.count, 5 if args.quick else args.subset,
                   args.quick)
    if args.only in (None, "lanes"):
        bench_lanes(args.quick)
    if args.only in (None, "ross-li"):
        bench_rossli(1000 if args.quick else 10_000, args.baseline, args.quick)


if __name__ == "__main__":
    main()
