"""Predictive intervals against held-out measurements (issue 13).

    .venv/bin/python benchmarks/bench_predictive.py [--quick] [--models five ggx auto] [--only ...]

Section ``predictive-real``: on every RT-300S run (the 8 new runs and the 6 legacy 1 deg
runs), each interior incidence is held out in turn; the model is fitted on the other
incidences (`brdfjax.fit`) and `brdfjax.predict` gives the 68 and 95 % intervals at the
held-out geometry, calibrated on the cross-validation of the training incidences alone.
Reported: the share of held-out measurements inside, pooled and per run, and the median
95 % half-width relative to the prediction.

Section ``predictive-synthetic``: where the model is exact: the paper's white paint
(five-parameter model, 716-point geometry at 10/21/30/45/52/60 deg), 2.5 % relative
noise, a new noise draw per replicate; 30 deg held out and predicted the same way.

Section ``predictive-discrepancy`` (``--only discrepancy``): the same held-out folds of the
14 RT-300S runs with the learned discrepancy (`brdfjax.prediction.discrepancy`) against the model
alone, per run: coverage, median 95 % half-width, median relative error of the prediction,
and each material's run-to-run repeatability. `DECIDE` are the runs looked at while the
method was built; the others confirm. Also draws `benchmarks/predictive_bands.png`: one
held-out incidence with both bands.

Section ``predictive-nist`` (``--only nist``): the same with NIST's PTFE at its four
wavelengths, real data that no setting of the discrepancy was chosen on.

Section ``predictive-3d`` (``--only 3d``): the folds of predictive-discrepancy on the 8
RT-300S runs that are whole 3-D scans, read whole and in the plane of incidence alone, side
by side, with `DECIDE`'s labels (issue 48).

Section ``predictive-speed`` (``--only speed``): the learned discrepancy's cost, as a user
meets it: whole commands, warm, with ``--discrepancy none`` and ``gp`` in turn (`fit
--predict` on 120 and 600 points, `models` on 120), and `brdfjax.predict` at 100,000
geometry points in this process.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from benchmarks import report
from benchmarks.report import load_average, real_data, time_commands, write_section

NIST = real_data("nist-germer-ptfe") / "PTFE.data.csv"
# The 8 runs of 2025, each a whole 3-D scan (the blank, blank_v2o0, is not one of them).
RUNS_3D = sorted((real_data("uaz-loft-rt300s") / "raw").glob("*_v1o0*.xls"))
RUNS = RUNS_3D + sorted((real_data("uaz-loft-rt300s") / "raw_legacy_1deg").glob("0*.xls"))


def fit_without(data, incidence, model):
    """``(model name, fit)`` of ``data`` with ``incidence`` held out. ``auto``: the model
    `brdfjax.prediction.selection.compare_models` recommends on the training incidences alone
    (`Comparison.best`, as ``brdfjax fit --model auto`` would choose)."""
    import brdfjax

    if model == "auto":
        model = choices(data, incidence, discrepancy="none")["none"]
    return model, brdfjax.fit(data, model=model, validate_incidences_deg=[incidence])


def choices(data, incidence, discrepancy: str) -> dict:
    """``--model auto``'s choices with ``incidence`` held out, as ``brdfjax fit`` makes them:
    ``{"none": the model recommended}`` (``Comparison.best``: the one-standard-error rule on
    cv_error) and, with ``discrepancy="gp"``, ``"gp"``: the model to predict with
    (``Comparison.predictor``: that model unless its corrected cv_error is more than one
    standard error above the lowest), which ``fit --model auto --predict`` uses.
    One comparison gives both."""
    from brdfjax.prediction.selection import compare_models

    comparison = compare_models(data.select(~data.incidence_mask([incidence])),
                                discrepancy=discrepancy)
    chosen = {"none": comparison.best.name}
    if discrepancy == "gp":
        chosen["gp"] = comparison.predictor.name
    return chosen


def held_out_predictions(data, model):
    """(inside95, inside68, half-widths, models used) of every interior incidence held out in
    turn (`fit_without`), predicted by the model alone (section predictive-discrepancy has
    the learned discrepancy)."""
    import brdfjax

    inside95, inside68, widths, used = [], [], [], []
    for incidence in data.incidences_deg[1:-1]:
        chosen, result = fit_without(data, incidence, model)
        used.append(chosen)
        prediction = brdfjax.predict(result, data.at_incidences([incidence]),
                                     discrepancy="none")
        measured = prediction.measured
        inside95.append((measured >= prediction.lo95) & (measured <= prediction.hi95))
        inside68.append((measured >= prediction.lo68) & (measured <= prediction.hi68))
        widths.append((prediction.hi95 - prediction.lo95) / 2 / np.abs(prediction.brdf))
    return (np.concatenate(inside95), np.concatenate(inside68), np.concatenate(widths),
            used)


def bench_real(models, runs):
    import brdfjax

    lines = ["## Predictive intervals on real held-out incidences", "",
             ("Each interior incidence of each run held out in turn (30 and 50 deg: every run "
             "has 10/30/50/70 deg), the model fitted on the rest, `brdfjax.predict` at the "
             "held-out geometry with the model alone (`discrepancy=\"none\"`). Target: 95 % "
             "intervals hold 90-99 % pooled, every run at least 75 %. The interval method "
             "(split-conformal, floor 5 % of the median) was fixed before any of these runs "
             "was looked at: no run was used for tuning."), "",
             ("| model | pooled 95 % | pooled 68 % | lowest run (95 %) | median 95 % half-width "
             "(of the prediction) |"), "|---|---|---|---|---|"]
    notes = []
    for model in models:
        per_run, all95, all68, all_widths, used = {}, [], [], [], []
        for path in runs:
            inside95, inside68, widths, chosen = held_out_predictions(brdfjax.load(path, in_plane=True), model)
            used += chosen
            per_run[path.name] = inside95.mean()
            all95.append(inside95)
            all68.append(inside68)
            all_widths.append(widths)
        lowest = min(per_run, key=per_run.get)
        lines.append(f"| {model} | {100 * np.concatenate(all95).mean():.1f} % | "
                     f"{100 * np.concatenate(all68).mean():.1f} % | "
                     f"{100 * per_run[lowest]:.1f} % ({lowest}) | "
                     f"{100 * np.median(np.concatenate(all_widths)):.0f} % |")
        if model == "auto":
            counts = ", ".join(f"{name} {used.count(name)}" for name in sorted(set(used)))
            notes.append(f"`auto` chose, over the {len(used)} folds: {counts} (chosen on each "
                         "fold's training incidences alone).")
    lines += ["", *notes] if notes else []
    write_section("predictive-real", "\n".join(lines))


def bench_synthetic(replicates):
    import brdfjax
    from brdfjax.data.measurements import Measurements

    white = brdfjax.load(REPO / "data" / "synthetic" / "white_paint.csv")
    clean = np.asarray(brdfjax.brdf(brdfjax.PAPER_SAMPLES["white_paint"], white.theta_i,
                                    white.theta_r, white.phi_r))
    inside95, inside68, widths = [], [], []
    for seed in range(replicates):
        noisy = clean * (1 + 0.025 * np.random.default_rng(1000 + seed).standard_normal(
            clean.size))
        data = Measurements(white.theta_i, white.theta_r, white.phi_r, noisy)
        result = brdfjax.fit(data, validate_incidences_deg=[30.0])
        prediction = brdfjax.predict(result, data.at_incidences([30.0]))
        m = prediction.measured
        inside95.append(np.mean((m >= prediction.lo95) & (m <= prediction.hi95)))
        inside68.append(np.mean((m >= prediction.lo68) & (m <= prediction.hi68)))
        widths.append(np.median((prediction.hi95 - prediction.lo95) / 2 / prediction.brdf))
    write_section("predictive-synthetic", "\n".join([
        "## Predictive intervals where the model is exact", "",
        (f"Synthetic white paint (the paper's parameters, 2.5 % noise), {replicates} "
        "replicates (noise seeds 1000 on), 30 deg held out and predicted with `brdfjax.predict`'s "
        "default (the model times its learned discrepancy); target 90-99 %, and a half-width "
        "within 1.5x of the noise's own 95 % (1.96 x 2.5 % = 4.9 %)."), "",
        "| 95 % coverage (mean over replicates) | 68 % coverage | median 95 % half-width |",
        "|---|---|---|",
        (f"| {100 * np.mean(inside95):.1f} % (replicates {100 * np.min(inside95):.0f}-"
        f"{100 * np.max(inside95):.0f} %) | {100 * np.mean(inside68):.1f} % | "
        f"{100 * np.median(widths):.1f} % |")]))


# Looked at while the discrepancy was built (its design and settings); the rest confirm.
DECIDE = ("NiTE_on_steel_v1o0A_20250915.xls", "02singularity.xls",
          "ANOPLATE_AnoBlack_EC1_Alum6061_v1o0_20251115.xls", "01aeroglaze.xls")
# The repeated runs of each material (A/B/C, 01/02/03).
MATERIALS = {"NiTE on steel": "NiTE_on_steel", "NiTE on invar": "NiTE_on_invar",
             "Singularity": "singularity", "Aeroglaze": "aeroglaze"}


def repeated(runs) -> dict:
    """``{material: its runs}`` of the materials of `MATERIALS` measured 3 times in ``runs``."""
    groups = {material: [p for p in runs if stem in p.name] for material, stem in MATERIALS.items()}
    return {material: paths for material, paths in groups.items() if len(paths) >= 3}


def by_geometry(data) -> dict:
    """``{(theta_i, theta_r, phi_r in [0, 360)) in degrees: BRDF}`` of a data set
    (`brdfjax.data.measurements.geometry_keys`)."""
    from brdfjax.data.measurements import geometry_keys

    keys = geometry_keys(*np.degrees([data.theta_i, data.theta_r, data.phi_r]))
    return dict(zip(map(tuple, keys), data.brdf))


def repeatability(paths, in_plane: bool = True) -> tuple[float, float]:
    """Over the geometries all runs share: the 95th percentile of ``|y - mean of the others| /
    (|mean| + 5 % of the median |BRDF|)`` (the issue's anchor for the intervals), and the
    median of ``|y - mean of the others| / |y|`` (on the scale of the median relative error
    of a prediction, ``|prediction - y| / |y|``)."""
    import brdfjax

    runs = [by_geometry(brdfjax.load(path, in_plane=in_plane)) for path in paths]
    shared = set.intersection(*(set(r) for r in runs))
    table = np.array([[r[k] for k in sorted(shared)] for r in runs])
    scores, relative = [], []
    for k in range(len(runs)):
        others = np.delete(table, k, axis=0).mean(axis=0)
        floor = 0.05 * np.median(np.abs(table[k]))
        scores.append(np.abs(table[k] - others) / (np.abs(others) + floor))
        relative.append(np.abs(table[k] - others) / np.abs(table[k]))
    return (float(np.percentile(np.concatenate(scores), 95)),
            float(np.median(np.concatenate(relative))))


def held_out_both(data, model):
    """Every interior incidence held out in turn, one fit and cross-validation for each
    model chosen, both intervals from it (``auto`` may choose one model for each kind):
    ``{kind: (inside95, inside68, half-widths, relative errors)}``, ``{kind: models used}``,
    and the first fold's predictions (for the figure)."""
    import warnings

    import brdfjax
    from brdfjax.prediction.cross_validation import cross_validate
    from brdfjax.prediction.intervals import calibrate, predict

    out = {kind: ([], [], [], []) for kind in ("none", "gp")}
    used, first = {kind: [] for kind in out}, {}
    for incidence in data.incidences_deg[1:-1]:
        held = data.at_incidences([incidence])
        chosen = (choices(data, incidence, discrepancy="gp") if model == "auto" else
                  dict.fromkeys(out, model))
        fitted = {}
        for name in set(chosen.values()):
            result = brdfjax.fit(data, model=name, validate_incidences_deg=[incidence])
            fitted[name] = (result, cross_validate(result.training, result.model,
                                                   bounds=result.bounds))
        for kind, lists in out.items():
            used[kind].append(chosen[kind])
            result, validation = fitted[chosen[kind]]
            calibration = calibrate(result.training, validation, discrepancy=kind,
                                    fitted=result.vector)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                prediction = predict(result, held, calibration)
            m = prediction.measured
            for values, new in zip(lists, (
                    (m >= prediction.lo95) & (m <= prediction.hi95),
                    (m >= prediction.lo68) & (m <= prediction.hi68),
                    prediction.half_width(),
                    np.abs(prediction.brdf - m) / np.abs(m))):
                values.append(new)
            if not first.get(kind):
                first[kind] = (incidence, held, prediction)
    return {k: [np.concatenate(v) for v in lists] for k, lists in out.items()}, used, first


def both_cells(results) -> str:
    """Table cells of `held_out_both`'s arrays, ``none / gp``: 95 and 68 % coverage, median
    95 % half-width, median relative error."""
    none, gp = results["none"], results["gp"]
    return (f"{100 * none[0].mean():.0f} / {100 * gp[0].mean():.0f} % | "
            f"{100 * none[1].mean():.0f} / {100 * gp[1].mean():.0f} % | "
            f"{100 * np.median(none[2]):.0f} / {100 * np.median(gp[2]):.0f} % | "
            f"{100 * np.median(none[3]):.1f} / {100 * np.median(gp[3]):.1f} %")


def pooled(results: list) -> dict:
    """Several sets' `held_out_both` arrays, concatenated: one result of the same shape."""
    return {kind: [np.concatenate([one[kind][i] for one in results]) for i in range(4)]
            for kind in results[0]}


def draw_bands(path, first, model):
    """`benchmarks/predictive_bands.png`: one held-out incidence with both bands."""
    from brdfjax.plot import plot_prediction_bands

    incidence, held, _ = first["gp"]
    plot_prediction_bands(held, {"model alone (--discrepancy none)": first["none"][2],
                                 "model x learned discrepancy (gp)": first["gp"][2]},
                          REPO / "benchmarks" / "predictive_bands.png",
                          title=f"{path.name}: {incidence:g} deg held out, predicted from "
                                f"the other incidences ({model})")


def bench_discrepancy(models, runs):
    import brdfjax

    anchors = {material: repeatability(paths) for material, paths in repeated(runs).items()}
    lines = ["## Predictions with a learned discrepancy, on real held-out incidences", "",
             ("The folds of predictive-real (each interior incidence of each run held out, the "
              "model fitted on the rest), predicted by the model alone (`--discrepancy none`) "
              "and by the model times its learned discrepancy (`--discrepancy gp`, the "
              "default), each with its split-conformal intervals from the training incidences' "
              "own cross-validation. Targets (issue 23): pooled 95 % coverage 90-99 %, every "
              "run at least 75 %, 68 % coverage 60-76 %, median 95 % half-width at most 25 %; "
              "held-out median relative error at most 5 % on the NiTE runs and 10 % on every "
              "run. Runs marked *decide* were looked at while the method was built; the "
              "others confirm it, except that two settings of the process (its incidence "
              "input and the lower bound of its length scale) and `--model auto`'s rule were "
              "chosen with the confirm runs in view (`benchmarks/NOTES.md` says when and "
              "how): for those, NIST's PTFE (section predictive-nist), which chose nothing, "
              "is the independent check."), "",
             "Run-to-run repeatability, the physical anchor (95th percentile of |y - mean of "
             "the other two runs| / (|mean| + 5 % of the median |BRDF|) at the geometries all "
             "three runs share): " + ", ".join(f"{m} {100 * v[0]:.0f} %"
                                              for m, v in anchors.items()) + ". "
             "On the scale of the median relative error (median of |y - mean of the other two "
             "runs| / |y|, the same geometries): " + ", ".join(
                 f"{m} {100 * v[1]:.1f} %" for m, v in anchors.items()) + " (a held-out "
             "incidence is predicted from its own run's other incidences, so the differences "
             "between runs are not part of its error).", ""]
    figure = None
    for model in models:
        lines += [f"### {model}", "",
                  ("| run | set | 95 % none / gp | 68 % none / gp | median 95 % half-width "
                   "none / gp | median rel. error none / gp | repeatability (95th pct. / median) |"),
                  "|---|---|---|---|---|---|---|"]
        pooled = {k: {"decide": [[], [], [], []], "confirm": [[], [], [], []]}
                  for k in ("none", "gp")}
        nite = {"none": [], "gp": []}  # the relative errors of the NiTE runs
        models_used = {"none": [], "gp": []}
        for path in runs:
            results, used, first = held_out_both(brdfjax.load(path, in_plane=True), model)
            for kind in models_used:
                models_used[kind] += used[kind]
            group = "decide" if path.name in DECIDE else "confirm"
            for kind, arrays in results.items():
                for store, values in zip(pooled[kind][group], arrays):
                    store.append(values)
                if path.name.startswith("NiTE"):
                    nite[kind].append(arrays[3])
            anchor = next((v for m, v in anchors.items() if MATERIALS[m] in path.name), None)
            lines.append(
                f"| {path.name} | {group} | {both_cells(results)} | "
                + (f"{100 * anchor[0]:.0f} % / {100 * anchor[1]:.1f} % |"
                   if anchor is not None else "- |"))
            if figure is None and path.name == DECIDE[0]:
                figure = (path, first, model)
        lines.append("")
        for group in ("decide", "confirm", "all"):
            cells = []
            for kind in ("none", "gp"):
                stores = pooled[kind]
                arrays = [np.concatenate(stores["decide"][i] + stores["confirm"][i])
                          if group == "all" else np.concatenate(stores[group][i])
                          for i in range(4)]
                cells.append(arrays)
            which = "all runs" if group == "all" else f"the {group} runs"
            lines.append(
                f"Pooled over {which}: 95 % coverage {100 * cells[0][0].mean():.1f} "
                f"/ {100 * cells[1][0].mean():.1f} %, 68 % {100 * cells[0][1].mean():.1f} / "
                f"{100 * cells[1][1].mean():.1f} %, median 95 % half-width "
                f"{100 * np.median(cells[0][2]):.0f} / {100 * np.median(cells[1][2]):.0f} %, "
                f"median relative error {100 * np.median(cells[0][3]):.1f} / "
                f"{100 * np.median(cells[1][3]):.1f} % (none / gp).")
            lines.append("")
        if nite["gp"]:
            lines += [(f"Pooled over the {len(nite['gp'])} NiTE runs: median relative error "
                       + " / ".join(f"{100 * np.median(np.concatenate(nite[k])):.2f}"
                                    for k in ("none", "gp"))
                       + " % (none / gp); the target reads per run in the table above."), ""]
        if model == "auto":
            ways = {"none": ("by the one-standard-error rule on cv_error (`Comparison.best`), "
                             "for the model alone"),
                    "gp": ("as `Comparison.predictor` (that model unless its cv_error times "
                           "its discrepancy is more than one standard error above the "
                           "lowest), for the corrected prediction")}
            for kind, what in ways.items():
                counts = ", ".join(f"{n} {models_used[kind].count(n)}"
                                   for n in sorted(set(models_used[kind])))
                lines += [(f"`auto` chose {what}, over the {len(models_used[kind])} folds: "
                           f"{counts}."), ""]
    if figure is not None:
        draw_bands(*figure)
        lines += [(f"One held-out incidence of {figure[0].name} with both bands "
                  f"(`benchmarks/predictive_bands.png`, {figure[2]}):"), "",
                  "![held-out incidence, both bands](benchmarks/predictive_bands.png)"]
    write_section("predictive-discrepancy", "\n".join(lines).rstrip())


NIST_WAVELENGTHS = (351, 532, 633, 1064)


def unseen_sets(quick: bool = False) -> dict:
    """``{label: (file, loader options)}``: real sets that chose none of the prediction's
    settings: another instrument (ScatterWorks' Starlink samples) and other surfaces on the
    RT-300S (an image sensor at two of its ten stage rotations, Magic Black v1), the
    3-D scans both whole and in the plane of incidence; and one RT-300S run of the tuning
    set read whole, which tuning saw only in the plane."""
    starlink = real_data("starlink-v1p5-scatterworks")
    rt300s = real_data("uaz-loft-rt300s")
    sets = {"Starlink chassis (ScatterWorks, in-plane)": (starlink / "chassis_brdf.csv", {}),
            "Starlink solar array (ScatterWorks, in-plane)": (
                starlink / "solar_array_brdf.csv", {}),
            "Magic Black v1 (RT-300S, in-plane, 1 deg)": (
                rt300s / "raw_magicblack_v1" / "MagicBlack_v1o0_20250829.xls", {})}
    # Magic Black v2 is left out: its blank-subtracted BRDF is negative at 88 of its 120
    # in-plane readings with either blank the folder holds, so no prediction can be scored.
    scans = {"IMX455 sensor, rotation 0": rt300s / "raw_more" / "IMX455_stageRotation0_20250922.xls",
             "IMX455 sensor, rotation 60": (
                 rt300s / "raw_more" / "IMX455_stageRotation60_20250922.xls"),
             "NiTE on steel A (tuning run)": rt300s / "raw" / "NiTE_on_steel_v1o0A_20250915.xls"}
    for label, path in scans.items():
        sets[f"{label} (RT-300S, in-plane)"] = (path, {"in_plane": True})
        sets[f"{label} (RT-300S, 3-D)"] = (path, {})
    return dict(list(sets.items())[:2]) if quick else sets


def bench_unseen(models, quick: bool):
    """Section predictive-unseen: the held-out folds of predictive-discrepancy on real sets
    of other instruments and surfaces (`unseen_sets`), none of which chose any setting."""
    import brdfjax

    lines = ['<a id="predictive-unseen"></a>',
             "## Predictions on instruments and surfaces never used to build them", "",
             ("Each interior incidence held out in turn, the model fitted on the others, and "
              "predicted by the model alone (`none`) and by the model times its learned "
              "discrepancy (`gp`), with the intervals calibrated on the training incidences' "
              "own cross-validation, as in section predictive-discrepancy. No setting of the "
              "discrepancy, the intervals or `auto` was chosen on these sets. Targets (issue "
              "48): 95 % coverage at least 85 % on every set, 90-99 % pooled; median 95 % "
              "half-width at most 35 %; median relative error at most 10 %."), "",
             ("| model | set | points | 95 % none / gp | 68 % none / gp | median 95 % "
              "half-width none / gp | median rel. error none / gp |"),
             "|---|---|---|---|---|---|---|"]
    for model in models:
        every = []
        for label, (path, options) in unseen_sets(quick).items():
            data = brdfjax.load(path, **options)
            results, _, _ = held_out_both(data, model)
            every.append(results)
            lines.append(f"| {model} | {label} | {len(data)} | {both_cells(results)} |")
            print(lines[-1], flush=True)
        lines.append(f"| {model} | **all sets** | | {both_cells(pooled(every))} |")
    write_section("predictive-unseen", "\n".join(lines))


READINGS = {"3-D": {}, "in-plane": {"in_plane": True}}


def mirror_asymmetry(data) -> str:
    """The median of ``|y(phi_r) - y(-phi_r)| / their mean`` over the readings out of the plane
    of incidence whose mirror image in that plane was read too, as a table cell: an isotropic
    sample reads both alike, and every isotropic model takes them for one geometry. ``-``
    where there is no such pair (in the plane)."""
    readings = by_geometry(data)
    differences = []
    for (theta_i, theta_r, phi_r), value in readings.items():
        mirror = readings.get((theta_i, theta_r, round(360.0 - phi_r, 6)))
        if 0 < phi_r < 180 and mirror is not None:
            differences.append(2 * abs(value - mirror) / abs(value + mirror))
    return f"{100 * np.median(differences):.0f} %" if differences else "-"


def bench_3d(models, runs):
    """Section predictive-3d: the held-out folds of predictive-discrepancy on the RT-300S
    runs read whole (3-D) and in the plane of incidence alone, side by side (issue 48)."""
    import brdfjax

    anchors = ", ".join(f"{material} {100 * repeatability(paths, in_plane=False)[1]:.1f} %"
                        for material, paths in repeated(runs).items())
    lines = ['<a id="predictive-3d"></a>',
             "## Predictions on the RT-300S runs read whole (3-D) and in the plane", "",
             ("The 8 RT-300S runs of 2025, each a whole 3-D scan (incidences 10/30/50/70 deg x "
              "19 azimuths x 33 receive angles, about 2,478 readings), read whole (`3-D`) and "
              "in the plane of incidence alone (`in-plane`, `--in-plane`: the 120 readings "
              "every earlier RT-300S section used). Each interior incidence (30, 50 deg) held "
              "out in turn, the model fitted on the others, and predicted by the model alone "
              "(`none`) and by the model times its learned discrepancy (`gp`), with the "
              "intervals calibrated on the training incidences' own cross-validation, as in "
              "section predictive-discrepancy, whose *decide* and *confirm* labels these "
              "runs keep. Every setting was chosen on the in-plane readings but two, chosen "
              "on 2026-12-07 with all 8 runs read whole in view (`benchmarks/NOTES.md`, "
              "predictive-3d): the discrepancy's signed half vector out of the plane, and the "
              "process-scaled score's division by the square root of the process's sigma "
              "(`intervals.SIGMA_POWER`). On these runs they are not confirmed; NIST's PTFE "
              "and the IMX455 sensor read whole (sections predictive-nist, "
              "predictive-unseen) chose nothing. Targets (issue "
              "48): 95 % coverage at least 85 % on every set, 90-99 % pooled; median 95 % "
              "half-width at most 35 %; median relative error at most 10 % on every set, "
              "and on the RT-300S runs at most 4.8 % pooled (in-plane auto with gp in "
              "predictive-discrepancy)."), "",
             ("*Mirror asymmetry*: the median of |y(phi_r) - y(-phi_r)| / their mean over the "
              "readings out of the plane of incidence whose mirror image in that plane was "
              "read too (the reader takes (Azimuth A, Receive R) and (-A, -R) for mirror "
              "images, as the authors' conversion does). An isotropic sample reads both alike, "
              "and every model here takes them for one geometry; the discrepancy, whose "
              "inputs out of the plane hold the half vector signed (since 2026-12-07; folded "
              "into one input before), learns the difference."
              + (" Against it, run-to-run repeatability read whole (median of |y - mean of "
                 "the other two runs| / |y| at the geometries all three share): "
                 f"{anchors}." if anchors else "")), ""]
    for model in models:
        lines += [f"### {model}", "",
                  ("| run | set | reading | points | 95 % none / gp | 68 % none / gp | median "
                   "95 % half-width none / gp | median rel. error none / gp | mirror "
                   "asymmetry |"),
                  "|---|---|---|---|---|---|---|---|---|"]
        groups = {(group, reading): [] for group in ("decide", "confirm")
                  for reading in READINGS}
        used = {reading: [] for reading in READINGS}
        for path in runs:
            group = "decide" if path.name in DECIDE else "confirm"
            for reading, options in READINGS.items():
                data = brdfjax.load(path, **options)
                results, chosen, _ = held_out_both(data, model)
                groups[group, reading].append(results)
                used[reading] += chosen["gp"]
                lines.append(f"| {path.name} | {group} | {reading} | {len(data)} | "
                             f"{both_cells(results)} | {mirror_asymmetry(data)} |")
                print(lines[-1], flush=True)
        for group in ("decide", "confirm", "all"):
            for reading in READINGS:
                sets = (groups["decide", reading] + groups["confirm", reading]
                        if group == "all" else groups[group, reading])
                if sets:
                    lines.append(f"| **{group} runs, pooled** | | {reading} | | "
                                 f"{both_cells(pooled(sets))} | |")
        lines.append("")
        if model == "auto":
            for reading, names in used.items():
                counts = ", ".join(f"{n} {names.count(n)}" for n in sorted(set(names)))
                lines += [(f"`auto` chose, for the corrected prediction, {reading}, over the "
                           f"{len(names)} folds: {counts}."), ""]
    write_section("predictive-3d", "\n".join(lines).rstrip())


def bench_nist(models):
    """Section predictive-nist: NIST's PTFE, held out as the RT-300S runs are in section
    predictive-discrepancy, data that were not looked at while the discrepancy was built."""
    import brdfjax

    lines = ["## Predictions with a learned discrepancy on real data not used to build it", "",
             ("NIST's PTFE (Germer; a near-Lambertian diffuser, BRDF 0.23-0.71 1/sr, median "
              "0.314; 1824 points out of the plane at each of four wavelengths, which differ "
              "by about 1 % at the median geometry, so that the four are nearly one surface "
              "measured four times; incidences 0, 15, 30, 45, 60 and 75 deg): each interior "
              "incidence (15-60 deg) "
              "held out in turn, the model fitted on the other five, predicted by the model "
              "alone (`--discrepancy none`) and by the model times its learned discrepancy "
              "(`gp`), each with its split-conformal intervals, as section "
              "predictive-discrepancy does for the RT-300S runs. Until 2026-12-06 these data "
              "served only to time predictions (section predictive-speed): no setting of the "
              "discrepancy or its intervals was chosen on them. Every process holds 256 "
              "points (`discrepancy.subsample`): of the about 1520 training points for the "
              "one that predicts, of about 1216 for each calibration fold's. Issue 23's "
              "targets were set for the RT-300S runs; here they are a check."), "",
             ("| model | wavelength (nm) | 95 % none / gp | 68 % none / gp | median 95 % "
              "half-width none / gp | median rel. error none / gp |"),
             "|---|---|---|---|---|---|"]
    notes = []
    for model in models:
        every, used = [], []
        for wavelength in NIST_WAVELENGTHS:
            results, chosen, _ = held_out_both(brdfjax.load(NIST, wavelength_nm=wavelength),
                                               model)
            used += chosen["gp"]
            every.append(results)
            lines.append(f"| {model} | {wavelength} | {both_cells(results)} |")
        lines.append(f"| {model} | all four | {both_cells(pooled(every))} |")
        if model == "auto":
            counts = ", ".join(f"{name} {used.count(name)}" for name in sorted(set(used)))
            notes.append(f"`auto` chose, for the corrected prediction, over the {len(used)} "
                         f"folds: {counts}.")
    write_section("predictive-nist", "\n".join(lines + ["", *notes]).rstrip())


def bench_speed(repeats):
    """Section predictive-speed (issue 23's speed targets)."""
    raw = RUNS[0].parent
    files = {"NiTE on steel A": (raw / "NiTE_on_steel_v1o0A_20250915.xls", 120),
             "02singularity": (raw.parent / "raw_legacy_1deg" / "02singularity.xls", 600)}
    cli = str(Path(sys.executable).parent / "brdfjax")
    with tempfile.TemporaryDirectory() as tmp:
        commands = {}
        for label, (path, _) in files.items():
            for kind in ("none", "gp"):
                commands["fit", label, kind] = [
                    cli, "fit", str(path), "--model", "ggx", "--uncertainty", "none",
                    "--predict", str(path), "--predict-out", f"{tmp}/p.csv",
                    "--discrepancy", kind, "--in-plane"]
        for kind in ("none", "gp"):
            commands["models", "NiTE on steel A", kind] = [
                cli, "models", str(files["NiTE on steel A"][0]), "--discrepancy", kind,
                "--in-plane"]
        times = time_commands(commands, repeats)
    load = load_average()

    def cell(values):
        return f"{np.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"

    lines = ["## Speed of predictions with the learned discrepancy", "",
             (f"Whole commands as a user runs them, warm (each run once first), the "
              f"commands taken in turn, {repeats} rounds; median (range) in seconds. `fit` "
              "predicts at the file's own geometry: `brdfjax fit FILE --model ggx "
              "--uncertainty none --predict FILE --predict-out P.csv --discrepancy none|gp`; "
              "`brdfjax models FILE --discrepancy none|gp` fits and cross-validates its "
              "default candidates. Targets (issue 23): `fit --predict` with the discrepancy "
              "at most 2x its time without; `models` with the discrepancy columns at most 8 s "
              "on 120 points."), "",
             ("| command | run (points) | `--discrepancy none` | `--discrepancy gp` | ratio | "
              "target | met |"), "|---|---|---|---|---|---|---|"]
    for command, label in dict.fromkeys(key[:2] for key in times):
        without, values = times[command, label, "none"], times[command, label, "gp"]
        ratio = np.median(values) / np.median(without)
        target, met = (("2x", ratio <= 2) if command == "fit" else
                       ("8 s", np.median(values) <= 8))
        lines.append(f"| `{command}` | {label} ({files[label][1]}) | {cell(without)} | "
                     f"{cell(values)} | {ratio:.2f}x | {target} | {'yes' if met else '**no**'} |")
    lines += ["", f"Load average (1 min) after the commands: {load}.", "",
              predict_many()]
    write_section("predictive-speed", "\n".join(lines))


def predict_many(count: int = 100_000, repeats: int = 4) -> str:
    """`brdfjax.predict` of ggx fitted to NIST PTFE at 633 nm (1824 points) at ``count``
    geometry points out of the plane: a paragraph with the first and the warm times."""
    import brdfjax
    from brdfjax.data.measurements import Measurements
    from brdfjax.prediction.cross_validation import cross_validate
    from brdfjax.prediction.intervals import calibrate, predict

    data = brdfjax.load(NIST, wavelength_nm=633)
    result = brdfjax.fit(data, model="ggx")
    validation = cross_validate(result.training, result.model, bounds=result.bounds)
    calibration = calibrate(result.training, validation, discrepancy="gp",
                            fitted=result.vector)
    rng = np.random.default_rng(0)
    geometry = Measurements.from_degrees(rng.uniform(0, 75, count), rng.uniform(0, 85, count),
                                         rng.uniform(0, 360, count), np.full(count, np.nan))
    times = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # incidences past the measured ones are said so
        for _ in range(repeats):
            tic = time.perf_counter()
            prediction = predict(result, geometry, calibration)
            times.append(time.perf_counter() - tic)
    assert np.all(np.isfinite(prediction.brdf)) and np.all(np.isfinite(prediction.hi95))
    warm = times[1:]
    return (f"`brdfjax.predict` at {count:,} geometry points out of the plane (uniform in "
            "theta_i 0-75 deg, theta_r 0-85 deg, phi_r 0-360 deg), ggx fitted to NIST PTFE at "
            f"633 nm ({len(data)} points; its process holds "
            f"{calibration.discrepancy.points} of them), in this process: the first call "
            f"{times[0]:.2f} s, then {', '.join(f'{t:.2f}' for t in warm)} s. Target 2 s "
            f"warm: {'met' if max(warm) <= 2 else '**not met**'}.")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 runs, 5 replicates, no writing")
    parser.add_argument("--models", nargs="+",
                        help="models, or auto (the choice of brdfjax fit --model auto); "
                             "default five ggx auto, and ggx alone for section predictive-3d")
    parser.add_argument("--only", nargs="+",
                        choices=("real", "synthetic", "discrepancy", "nist", "speed", "unseen",
                                 "3d"))
    args = parser.parse_args()
    report.DRY_RUN = args.quick
    models = args.models or ["five", "ggx", "auto"]
    if "real" in (args.only or ["real"]):
        bench_real(models, RUNS[:3] if args.quick else RUNS)
    if "synthetic" in (args.only or ["synthetic"]):
        bench_synthetic(5 if args.quick else 50)
    if "discrepancy" in (args.only or ["discrepancy"]):
        bench_discrepancy(models, RUNS[:3] if args.quick else RUNS)
    if "nist" in (args.only or ["nist"]):
        bench_nist(models)
    if "speed" in (args.only or ["speed"]):
        bench_speed(1 if args.quick else 5)
    if "unseen" in (args.only or ["unseen"]):
        bench_unseen(models, args.quick)
    if "3d" in (args.only or ["3d"]):
        # ggx alone by default: read whole, a run took about a minute with ggx and more than
        # 12 min with auto (its 10 candidates' processes of 256 points, each fold), with the
        # machine loaded 8-15 (2026-12-07).
        bench_3d(args.models or ["ggx"], RUNS_3D[:2] if args.quick else RUNS_3D)


if __name__ == "__main__":
    main()
