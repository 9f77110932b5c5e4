"""Adaptive measurement: read what the prediction needs, and stop when it is good enough.

`measure_adaptive` closes the loop of `brdfjax.instrument.design.plan` over the instrument.
The region is where the prediction is wanted (a grid plan's geometries); the candidates are
the geometries the loop may read (by default the region's own):

1. **Start:** ``start`` readings spread over the candidates (greedy maximin, no data).
2. **Assess:** the readings so far are fitted (``model``; ``auto``: the model ``brdfjax
   models`` recommends for prediction, chosen again each round) and the prediction, the
   model times its learned discrepancy, is made over the region with its conformal 95 %
   intervals (`brdfjax.prediction.intervals.predict`), calibrated on the loop's own
   batches (`calibrated`; on held-out incidences until there are enough). The round's
   width is the median over the region of the 95 % half-width relative to the prediction.
3. **Stop** when that width, calibrated by the batches, is at most ``target_width`` and
   the newest batch fell inside the previous round's intervals (`CHECKED`); when the
   width has levelled off above the target (`levelled`); when ``max_readings`` readings
   or ``max_minutes`` of instrument time are spent (checked between batches); or when no
   candidate is left.
4. **Plan** otherwise the next ``batch`` readings, those that most reduce the integrated
   variance of the discrepancy over the region (ALC), in a short route; read them; back to 2.

**The batches calibrate.** Each batch was predicted by the previous round before it was
read, so its readings give conformal scores out of sample at the geometries the loop
reads (`batch_scores`, in either form of conformal score). The cross-validation
holds whole incidences out, harder than the readings left on incidences already measured;
once the batches hold `BATCH_SCORES` scores, they alone set the factor of a round's
intervals inside the measured incidences (extrapolation keeps the cross-validation's).

**The journal** (`brdfjax.instrument.acquire.Journal`) is ``measure``'s: its first line
holds the run's settings (`Settings`: the region, a digest of the candidates, the model,
seed, reading settings and score form; not the stop rule, so that a finished run can be
resumed with a smaller target or a larger budget). A ``batch`` line lists a batch's
geometries before any is read, each ``reading`` line carries the instrument seconds it took
(motors, changer, integrations), and a ``round`` line holds each assessment. A rerun with
the same journal replays it: recorded batches are read (only their missing readings), not
planned again; recorded rounds are not fitted again; from there the same seed makes the
same decisions. Nothing read is lost or read twice.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from brdfjax.data.measurements import DataError, Measurements
from brdfjax.instrument.acquire import (
    TARGETS,
    Journal,
    check_reference,
    connected,
    file_metadata,
    to_measurements,
)
from brdfjax.instrument.plan import Plan

START_READINGS = 20
BATCH_READINGS = 10
# The stop on the width also asks that the newest batch, read after the previous round's
# prediction and chosen where that prediction was least sure, fell inside its 95 %
# intervals at least this often: an out-of-sample check of the calibration (at most one
# miss in a batch of 10). Without it, the first calibrated width, resting on the few
# held-out scores of 2-3 interior incidences, stopped 1 of 3 RT-300S scans at 2.5 % with
# 57.5 % of the rest covered.
CHECKED = 0.9
# The batches calibrate a round's intervals (`calibrated`) once they hold this many scores,
# the fewest whose conformal 95 % quantile is finite (ceil((n + 1) 0.95) <= n); the stop on
# the width waits for them. Until then the cross-validation calibrates, and on the RT-300S
# scans its held-out incidences, harder than the readings left on measured incidences, made
# intervals that covered 99-100 % of those on 9 of 14 scans.
BATCH_SCORES = 19
# The width has levelled off when the last LEVELLED_ROUNDS calibrated rounds narrowed it by
# less than LEVELLED_GAIN (relative) below the narrowest before them: it is then set by
# what the model and its discrepancy miss between the measured incidences, and reading
# more of the same geometries does not narrow it (on a legacy RT-300S scan of 4 incidences
# the width wandered between 28 and 42 % for 20 rounds, 250 readings, at a 20 % target).
LEVELLED_ROUNDS = 5
LEVELLED_GAIN = 0.05
STOPPED = {"target": "the target width was reached",
           "levelled": "the width levelled off above the target",
           "max-readings": "the reading budget (--max-readings) was spent",
           "max-minutes": "the time budget (--max-minutes) was spent",
           "candidates": "every candidate geometry was read"}


@dataclass(frozen=True)
class Settings:
    """What decides an adaptive run's readings (the journal's first line): the region's
    geometries, the candidates' digest (`digest`), the fit's and the readings' settings,
    and the power of sigma in the process-scaled score
    (`brdfjax.prediction.intervals.SIGMA_POWER`), in which the journal's batch scores were
    computed: a journal scored another way is refused, not mixed."""

    region: tuple
    candidates: str
    model: str
    seed: int
    start: int
    batch: int
    average: int
    integration_ms: float
    beam_margin: float
    sigma_power: float

    def to_dict(self) -> dict:
        record = asdict(self)
        record["region"] = [list(g) for g in self.region]
        return {"adaptive": record}


@dataclass(frozen=True)
class Round:
    """One assessment: after ``readings`` readings and ``minutes`` of instrument time, the
    prediction of ``model`` had a median 95 % half-width of ``half_width`` (relative; inf
    when it could not be made: too few incidences or a failed fit); ``checked`` is the
    share of the round's newest batch inside the previous round's 95 % intervals (None
    when there were none), ``scores`` its conformal scores against that prediction in
    either form of score (`batch_scores`), and ``by_batches`` whether the batches' scores
    calibrated this round (`calibrated`)."""

    readings: int
    minutes: float
    model: str
    half_width: float
    checked: float | None = None
    scores: dict | None = None
    by_batches: bool = False


@dataclass(frozen=True)
class AdaptiveResult:
    """The outcome of `measure_adaptive`.

    Attributes:
        data: the measurements written to the output file.
        rounds: every assessment, in order.
        stopped: why it stopped: ``target``, ``levelled``, ``max-readings``,
            ``max-minutes`` or ``candidates`` (none left).
        target_width: the stop rule's width (relative).
        read_now, resumed, resends: readings taken by this run, taken from the journal, and
            commands resent.
        journal: the journal's path.
        fit, calibration: the last round's fit and calibration (`calibrated`; None where
            the last round made no calibrated prediction): `predict`.
    """

    data: Measurements
    rounds: list
    stopped: str
    target_width: float
    read_now: int
    resumed: int
    resends: int
    journal: Path
    fit: object = None
    calibration: object = None

    def predict(self, geometry: Measurements):
        """The last round's prediction at ``geometry``, with the intervals the stop rule
        measured (`brdfjax.prediction.intervals.Prediction`)."""
        if self.fit is None:
            raise ValueError("the last round made no calibrated prediction")
        return _predict(self.fit, geometry, self.calibration)

    def report(self) -> list[str]:
        """The run in a few lines."""
        last = self.rounds[-1]
        why = STOPPED[self.stopped]
        if self.stopped == "target":
            why = (f"the median 95 % half-width is at most {100 * self.target_width:g} %, and "
                   "the newest batch fell inside the previous round's intervals")
        elif self.stopped == "levelled":
            why = (f"the median 95 % half-width levelled off above the target "
                   f"{100 * self.target_width:g} % ({LEVELLED_ROUNDS} rounds without "
                   f"narrowing it by {100 * LEVELLED_GAIN:g} %): it is set by what the model "
                   "misses between the measured incidences, and more readings of these "
                   "geometries will not narrow it; give candidates at other incidences "
                   "(--candidates), or accept this width")
        lines = [f"adaptive: stopped after {len(self.rounds)} round(s): {why}",
                 (f"adaptive: {len(self.data)} geometries read (sample + reference each) in "
                  f"{last.minutes:.1f} instrument minutes; model {last.model}; median 95 % "
                  f"half-width over the region {_percent(last.half_width)}")]
        lines += [f"  round {k}: {r.readings:4d} readings, {r.minutes:6.1f} min, {r.model}, "
                  f"half-width {_percent(r.half_width)}"
                  + ("" if r.checked is None else
                     f"; newest batch inside the last intervals: {100 * r.checked:.0f} %")
                  + ("; intervals calibrated by the batches" if r.by_batches else "")
                  for k, r in enumerate(self.rounds)]
        return lines


def digest(candidates: Measurements) -> str:
    """A short fingerprint of a candidate set's geometries (degrees to 1e-6)."""
    angles = np.round(np.degrees([candidates.theta_i, candidates.theta_r,
                                  np.mod(candidates.phi_r, 2 * np.pi)]), 6)
    return hashlib.sha256(np.ascontiguousarray(angles.T).tobytes()).hexdigest()[:16]


def check_settings(region: Measurements, candidates: Measurements | None, *,
                   target_width: float, model: str, start: int, batch: int, max_readings,
                   max_minutes) -> None:
    """Refuse bad settings in one line naming the option, before any motor moves;
    ``region``: the plan's geometry (`region_geometry`), ``candidates`` None for it."""
    from brdfjax.instrument.design import check_inputs
    from brdfjax.models import get

    if not target_width > 0:
        raise ValueError(f"--target-width {_percent(target_width)}: give the median 95 % "
                         "half-width to stop at, above 0 (for example 10 for 10 %)")
    for option, value in (("--start", start), ("--batch", batch)):
        if value < 1:
            raise ValueError(f"{option} {value}: give a whole number of readings, at least 1")
    if max_readings is not None and max_readings < start:
        raise ValueError(f"--max-readings {max_readings}: fewer than the {start} readings of "
                         "the start (--start)")
    if max_minutes is not None and not max_minutes > 0:
        raise ValueError(f"--max-minutes {max_minutes:g}: give a time above 0")
    if model != "auto":
        try:
            size = get(model).size
        except ValueError as problem:
            raise ValueError(f"--model {model}: {problem}") from None
        if start <= size:
            raise ValueError(f"--start {start}: {model} has {size} parameters; a prediction "
                             f"needs more readings than that to start from (give --start "
                             f"{max(2 * size, START_READINGS)})")
    check_inputs(region if candidates is None else candidates, start, region=region,
                 names={"budget": "--start", "candidates": "the candidates",
                        "region": "the region (the plan's grid)"})


def measure_adaptive(port: str, region: Plan, out, *, candidates: Measurements | None = None,
                     target_width: float = 0.10, model: str = "ggx", seed: int = 0,
                     start: int = START_READINGS, batch: int = BATCH_READINGS,
                     max_readings: int | None = None, max_minutes: float | None = None,
                     journal=None, reference_reflectance: float = 0.99, baud: int = 115200,
                     timeout: float = 1.0, retries: int = 5, metadata: dict | None = None,
                     progress: bool = True, plot=None) -> AdaptiveResult:
    """Measure adaptively on the instrument at ``port`` until the prediction over
    ``region`` is as narrow as ``target_width`` (see the module docstring).

    Args:
        port: the instrument's serial device.
        region: a grid plan whose geometries the prediction is for; its ``average``,
            ``integration_ms`` and ``beam_margin`` are every reading's.
        out: the measurement file to write.
        candidates: the geometries that may be read (default: the region's).
        target_width: the median relative 95 % half-width to stop at (0.10: 10 %).
        model: the model that predicts (a name, or ``auto``).
        seed: seeds the start, the fits and the cross-validation.
        start, batch: readings of the space-filling start and of each later batch.
        max_readings, max_minutes: budgets (None: no limit), checked between batches.
        journal: the journal file (default: ``out`` with the suffix ``.journal.jsonl``).
        reference_reflectance, baud, timeout, retries, metadata: as in
            `brdfjax.instrument.acquire.measure`.
        progress: show progress (readings, minutes, width against the target) on stderr.
        plot: write the figure of width against readings there (None: no figure).

    Returns:
        An `AdaptiveResult`.
    """
    points = region_geometry(region)
    candidates = points if candidates is None else candidates
    check_reference(reference_reflectance)
    check_settings(points, candidates, target_width=target_width, model=model, start=start,
                   batch=batch, max_readings=max_readings, max_minutes=max_minutes)
    from brdfjax.prediction.intervals import SIGMA_POWER

    settings = Settings(tuple(p.angles for p in region.points), digest(candidates), model,
                        seed, start, batch, region.average, region.integration_ms,
                        region.beam_margin, SIGMA_POWER)
    journal_path = Path(out).with_suffix(".journal.jsonl") if journal is None else journal
    record = Journal(journal_path, settings)
    loop = _Loop(record, settings, candidates, points,
                 reference_reflectance, progress)
    try:
        resumed = len(record.readings)
        with connected(port, record, region, baud=baud, timeout=timeout,
                       retries=retries) as session:
            stopped = loop.run(session, target_width, max_readings, max_minutes)
            resends = session.instrument.resends
        data = to_measurements(loop.plan, record.readings, reference_reflectance,
                               file_metadata(out, record, reference_reflectance, metadata,
                                             f"; read adaptively ({model}), stopped on "
                                             f"{stopped}"))
    finally:
        record.close()
    from brdfjax.data.formats import save

    result = AdaptiveResult(data, loop.rounds[:loop.last + 1], stopped, target_width,
                            len(record.readings) - resumed, resumed, resends,
                            Path(journal_path), *loop.final())
    save(data, out)
    if plot is not None:
        plot_rounds(result, plot, title=f"{Path(out).stem}: adaptive measurement")
    return result


class _Loop:
    """The rounds of an adaptive run over an open journal: batches and rounds already in
    it are replayed, the rest measured and decided."""

    def __init__(self, record: Journal, settings: Settings, candidates: Measurements,
                 region: Measurements, reference_reflectance: float, progress: bool):
        self.record, self.settings = record, settings
        self.candidates, self.region, self.progress = candidates, region, progress
        self.reference_reflectance = reference_reflectance
        self.batches = [tuple(map(tuple, b["geometries"])) for b in record.kept("batch")]
        self.rounds = [Round(r["readings"], r["minutes"], r["model"],
                             math.inf if r["half_width"] is None else r["half_width"],
                             r["checked"], r.get("scores"), r.get("by_batches", False))
                       for r in record.kept("round")]
        self.fits = {}  # round -> its fit, where made in this run
        self.last = 0  # the round the run stopped at (`run`)
        self.plan = None

    def run(self, session, target_width, max_readings, max_minutes) -> str:
        from tqdm import tqdm

        total = max_readings or len(self.candidates)
        with tqdm(total=total, unit="reading", desc="measure --adaptive", dynamic_ncols=True,
                  disable=not self.progress) as bar:
            if not self.batches:
                self._add_batch(self._next(None, self.settings.start))
            for k in range(len(self.candidates)):  # at most one round per candidate
                self.plan = self._plan(k)
                todo = [(p, t) for p in self.plan.points[-len(self.batches[k]):]
                        for t in TARGETS if (p.index, t) not in self.record.readings]
                bar.n = len(self.plan.points) - len({p.index for p, _ in todo})
                bar.refresh()
                session.read(self.plan, todo, self.record, lambda: bar.update(1))
                if k == len(self.rounds):
                    self._assess(k)
                done = self.rounds[k]
                bar.set_postfix_str(f"{done.minutes:.1f} min, half-width "
                                    f"{_percent(done.half_width)} (target "
                                    f"{_percent(target_width)}), {done.model}")
                readings, self.last = len(self.plan.points), k
                stopped = _stop(self.rounds[:k + 1], readings, len(self.candidates),
                                target_width, max_readings, max_minutes)
                if stopped:
                    return stopped
                if k + 1 == len(self.batches):
                    size = min(self.settings.batch, len(self.candidates) - readings,
                               (max_readings or math.inf) - readings)
                    self._add_batch(self._next(self._data(k), int(size), done.model))
        return "candidates"

    def _plan(self, k: int) -> Plan:
        """The instrument plan of the batches up to ``k``."""
        return Plan(geometries=sum(self.batches[:k + 1], ()), average=self.settings.average,
                    integration_ms=self.settings.integration_ms,
                    beam_margin=self.settings.beam_margin)

    def _data(self, k: int, only_last: bool = False) -> Measurements:
        """The readings of the batches up to ``k`` (of batch ``k`` alone: ``only_last``)."""
        data = to_measurements(self._plan(k), self.record.readings,
                               self.reference_reflectance, {})
        if only_last:
            data = data.select(np.arange(len(data)) >= len(data) - len(self.batches[k]))
        return data

    def _next(self, data, size, model=None) -> tuple:
        """The next batch's geometries, in route order."""
        from brdfjax.instrument.design import plan

        if model is not None and model.startswith("auto"):
            model = "ggx"  # auto could not choose yet (too few incidences)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            chosen = plan(data, self.candidates, size, region=self.region,
                          model=model or "ggx", seed=self.settings.seed)
        return tuple(zip(*(np.round(a, 6).tolist() for a in
                           (chosen.theta_i, chosen.theta_r, chosen.phi_r))))

    def _add_batch(self, geometries: tuple) -> None:
        self.record.append({"kind": "batch", "round": len(self.batches),
                            "geometries": [list(g) for g in geometries]})
        self.batches.append(geometries)

    def _fit(self, k: int):
        """``(model, fit)`` of round ``k`` (`fitted`), made once per run."""
        if k not in self.fits:
            self.fits[k] = fitted(self._data(k), self.settings.model, self.settings.seed)
        return self.fits[k]

    def _scored(self, k: int) -> list:
        """The scores of the batches checked up to round ``k`` (journaled)."""
        return [r.scores for r in self.rounds[:k + 1] if r.scores]

    def _assess(self, k: int) -> None:
        model, result = self._fit(k)
        checked = scores = None
        seed = self.settings.seed
        if k > 0 and math.isfinite(self.rounds[k - 1].half_width):
            before, batch = self._fit(k - 1)[1], self._data(k, only_last=True)
            calibration = calibrated(before, seed, self._scored(k - 1))[0]
            checked = float(np.mean(scaled_errors(before, calibration, batch) <= 1))
            scores = batch_scores(before, seed, batch)
        scored = self._scored(k - 1) + ([] if scores is None else [scores])
        width, by_batches = assess(result, self.region, seed, scored)
        minutes = sum(r.get("seconds", 0.0) for r in self.record.readings.values()) / 60
        done = Round(len(self._plan(k).points), minutes, model, width, checked, scores,
                     by_batches)
        finite = {"half_width": width if math.isfinite(width) else None}  # JSON has no inf
        self.record.append({"kind": "round", **asdict(done), **finite})
        self.rounds.append(done)

    def final(self) -> tuple:
        """The fit and calibration of the round the run stopped at (`last`: a resumed run
        with a looser stop rule stops before the journal's last round); None, None where it
        made no calibrated prediction."""
        if not math.isfinite(self.rounds[self.last].half_width):
            return None, None
        result = self._fit(self.last)[1]
        return result, calibrated(result, self.settings.seed, self._scored(self.last))[0]


def fitted(data: Measurements, model: str, seed: int) -> tuple:
    """``(model, fit)``: the model that predicts (``auto`` chosen as ``brdfjax models``
    recommends) and its fit, calibrated by cross-validation (kept in the fit, as
    `brdfjax.prediction.intervals.predict` keeps it); no fit when no calibrated prediction
    can be made yet (fewer than 3 incidences, or the fit failed or is underdetermined)."""
    from brdfjax.fitting.fit import fit
    from brdfjax.prediction.intervals import predict

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            if model == "auto":
                from brdfjax.instrument.design import auto_model

                model = auto_model(data, seed)
            result = fit(data, model=model, seed=seed)
            if result.status in ("failed", "underdetermined"):
                return model, None
            predict(result, data, seed=seed)  # the cross-validation, kept in the fit
        except DataError:  # too few incidences to hold one out
            return model if model != "auto" else "auto (not yet)", None
    return model, result


def assess(result, region: Measurements, seed: int, scored: list) -> tuple:
    """``(width, by_batches)``: the median over ``region`` of a round's calibrated 95 %
    half-width (relative; inf without a fit, `fitted`), and whether the batches' scores
    ``scored`` calibrated it (`calibrated`)."""
    if result is None:
        return math.inf, False
    calibration, by_batches = calibrated(result, seed, scored)
    prediction = _predict(result, region, calibration)
    return float(np.median(prediction.half_width())), by_batches


def calibrated(result, seed: int, scored: list) -> tuple:
    """``(calibration, by_batches)``: the fit's cross-validated calibration, its interior
    scores replaced by the checked batches' (``scored``: `batch_scores` per batch) in its
    own form once there are `BATCH_SCORES` of them."""
    calibration = result.calibrations["gp", seed]
    scores = np.array([s for found in scored for s in found[calibration.score]])
    if scores.size < BATCH_SCORES:
        return calibration, False
    return replace(calibration, interior=scores), True


def batch_scores(result, seed: int, readings: Measurements) -> dict:
    """The conformal scores of ``readings`` against a round's prediction (`fitted`) in
    either form of `brdfjax.prediction.intervals` (``sigma``, ``relative``), whichever its
    calibration chose (a later round may choose the other): each reading's distance from
    the prediction in units of an interval of that form whose factor is 1."""
    calibration = result.calibrations["gp", seed]
    unit = np.ones(100)  # every conformal quantile of 100 ones is 1
    return {form: scaled_errors(result, replace(calibration, interior=unit, every=unit,
                                                score=form), readings).tolist()
            for form in ("sigma", "relative")}


def scaled_errors(result, calibration, readings: Measurements) -> np.ndarray:
    """Each reading's distance from the prediction of ``result`` in units of the 95 %
    half-width of its interval under ``calibration`` (at most 1: inside), in the
    interval's own form: relative, or in ``log(y + floor)`` (the process-scaled score)."""
    prediction = _predict(result, readings, calibration)
    measured, centre, high = prediction.measured, prediction.brdf, prediction.hi95
    if calibration.score == "sigma":
        floor = calibration.discrepancy.floor
        measured = np.log(np.maximum(measured, 0.0) + floor)
        centre, high = np.log(centre + floor), np.log(high + floor)
    return np.abs(measured - centre) / (high - centre)


def _predict(result, geometry: Measurements, calibration):
    from brdfjax.prediction.intervals import predict

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return predict(result, geometry, calibration)


def _stop(rounds: list, readings: int, candidates: int, target_width, max_readings,
          max_minutes) -> str | None:
    """Why the run stops after the last of ``rounds``, or None."""
    done = rounds[-1]
    if (done.half_width <= target_width and (done.checked or 0.0) >= CHECKED
            and done.by_batches):
        return "target"
    if levelled(rounds):
        return "levelled"
    if max_readings is not None and readings >= max_readings:
        return "max-readings"
    if max_minutes is not None and done.minutes >= max_minutes:
        return "max-minutes"
    if readings >= candidates:
        return "candidates"
    return None


def levelled(rounds: list) -> bool:
    """Whether the width has levelled off (`LEVELLED_ROUNDS`, `LEVELLED_GAIN`): the
    narrowest of the last rounds is not clearly below the narrowest of the calibrated
    rounds before them."""
    widths = [r.half_width for r in rounds if math.isfinite(r.half_width)]
    if len(widths) <= LEVELLED_ROUNDS:
        return False
    before, last = widths[:-LEVELLED_ROUNDS], widths[-LEVELLED_ROUNDS:]
    return min(last) > (1 - LEVELLED_GAIN) * min(before)


def plot_rounds(result: AdaptiveResult, path, title: str = "") -> None:
    """The median 95 % half-width against readings (instrument minutes on the top axis),
    with the target."""
    from brdfjax.data.formats import replace_atomically
    from brdfjax.plot import _pyplot

    plt = _pyplot()
    readings = np.array([r.readings for r in result.rounds], float)
    minutes = np.array([r.minutes for r in result.rounds])
    width = 100 * np.array([r.half_width for r in result.rounds])
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    shown = np.isfinite(width)
    ax.plot(readings[shown], width[shown], "o-", color="C0", label="median 95 % half-width")
    for n in readings[~shown]:
        ax.axvline(n, color="0.7", lw=0.8, ls=":")
    ax.axhline(100 * result.target_width, color="C3", ls="--",
               label=f"target {100 * result.target_width:g} %")
    ax.set_ylim(0, 1.3 * max(np.max(width[shown], initial=0), 100 * result.target_width))
    ax.set_xlabel("readings (each: sample + reference)")
    ax.set_ylabel("median 95 % half-width over the region (%)")
    if len(readings) > 1 and np.all(np.diff(minutes) > 0):
        from matplotlib.ticker import MaxNLocator

        top = ax.secondary_xaxis("top", functions=(
            lambda n: np.interp(n, readings, minutes), lambda m: np.interp(m, minutes, readings)))
        top.xaxis.set_major_locator(MaxNLocator(5))
        top.set_xlabel("instrument minutes")
    models = dict.fromkeys(r.model for r in result.rounds)
    about = f"model: {', '.join(models)}; stopped: {STOPPED[result.stopped]}"
    note = "dotted lines: rounds without a calibrated prediction yet" if (~shown).any() else ""
    ax.set_title("\n".join(filter(None, [title, about, note])), fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    replace_atomically(path, lambda temporary: fig.savefig(temporary, dpi=120))
    plt.close(fig)


def region_geometry(region: Plan) -> Measurements:
    """Geometry-only `Measurements` of a plan's points."""
    theta_i, theta_r, phi_r = np.array([p.angles for p in region.points], float).T
    return Measurements.from_degrees(theta_i, theta_r, phi_r, np.full(theta_i.size, np.nan))


def _percent(width: float) -> str:
    return "none yet" if not math.isfinite(width) else f"{100 * width:.3g} %"
