"""Journaled acquisition: run a plan on the instrument and write a measurement file.

Every point of a `~brdfjax.instrument.plan.Plan` is read twice at the same geometry, once on
the sample and once on the PTFE reference plate (the paper's "measurements in pairs"), and
converted by the reference-sample method, Eq. (7)-(8):

    f_sample = (V_sample / V_ref) * rho_ref / pi

with ``rho_ref`` the plate's hemispherical reflectance, an input. The uncertainty of each
voltage is its integrations' ``std / sqrt(count)``, propagated to ``f`` to first order.

Every reading is appended to a journal (JSON lines, flushed and fsynced before the next
command) as soon as it arrives. The journal's first line holds the plan; a later run with
the same journal and plan reads only what is missing, so an interrupted acquisition resumes
without repeating or losing a point (a line cut short by a crash is dropped). A journal
written for another plan is refused. The journal keeps raw voltages, so ``rho_ref`` may be
changed on a rerun. At the end the result is written as a brdfjax CSV (or any format
`brdfjax.data.formats.save` writes) that ``brdfjax fit`` reads.
"""

from __future__ import annotations

import fcntl
import json
import math
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from brdfjax.data.measurements import DataError, Measurements
from brdfjax.instrument.plan import Plan

JOURNAL_VERSION = 1
TARGETS = ("sample", "reference")


@dataclass(frozen=True)
class MeasureResult:
    """The outcome of `measure`.

    Attributes:
        data: the measurements written to the output file.
        read_now: readings taken by this run.
        resumed: readings taken from the journal (an earlier, interrupted run).
        resends: commands the driver had to resend (timeouts, bad checksums).
        journal: the journal's path.
    """

    data: Measurements
    read_now: int
    resumed: int
    resends: int
    journal: Path


class Journal:
    """The append-only record of an acquisition (JSON lines), locked while open.

    Args:
        path: the journal file; created with the plan as its first line if missing.
        plan: the plan being measured; an existing journal must hold the same.
    """

    def __init__(self, path, plan: Plan):
        self.path = Path(path)
        # Held open (and locked) for the journal's whole life, closed by `close`.
        self._handle = open(self.path, "a+", encoding="utf-8")  # noqa: SIM115
        try:
            fcntl.flock(self._handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            self._handle.close()
            raise DataError("the journal is in use by another acquisition", self.path) from None
        self.readings: dict[tuple[int, str], dict] = {}
        self.instrument: dict = {}  # what the last connected instrument said to IDN?
        self._other: list[dict] = []  # the plan line and any other records
        if self.path.stat().st_size:
            try:
                self._load(plan)
            except DataError:
                self._handle.close()  # kept whatever it holds: not a journal of this run
                raise
        if self.path.stat().st_size == 0:
            self.append({"kind": "plan", "version": JOURNAL_VERSION, "plan": plan.to_dict()})

    def _load(self, plan: Plan) -> None:
        self._handle.seek(0)
        *lines, cut_short = self._handle.read().split("\n")
        for number, text in enumerate(lines, start=1):
            try:
                record = json.loads(text)
            except json.JSONDecodeError:
                raise DataError("not a JSON line", self.path, number,
                                "only the last line of a journal can be cut short") from None
            if number == 1 and record.get("plan") != plan.to_dict():
                raise DataError("this journal was written for another plan", self.path,
                                hint="its plan differs from this run's in "
                                     f"{_differences(record.get('plan'), plan.to_dict())}; "
                                     "measure that plan again, or give a new --journal")
            key = (record.get("point"), record.get("target"))
            if record.get("kind") == "reading" and key in self.readings:
                raise DataError(f"reading {key} appears twice", self.path, number)
            self._remember(record)
        if cut_short:  # a crash mid-write; drop it so that appends start on a new line
            self._handle.truncate(self.path.stat().st_size - len(cut_short.encode()))

    def _remember(self, record: dict) -> None:
        if record.get("kind") == "reading":
            self.readings[(record["point"], record["target"])] = record
        elif record.get("kind") == "instrument":
            self.instrument = record["instrument"]
        else:
            self._other.append(record)

    def kept(self, kind: str) -> list[dict]:
        """The records of ``kind`` other than readings (an adaptive run's ``batch`` and
        ``round`` lines), in the order written."""
        return [record for record in self._other if record.get("kind") == kind]

    def append(self, record: dict) -> None:
        """Write one record and make it durable before returning."""
        record["time"] = datetime.now(UTC).isoformat(timespec="milliseconds")
        self._handle.write(json.dumps(record) + "\n")
        self._handle.flush()
        os.fsync(self._handle.fileno())
        self._remember(record)

    def close(self) -> None:
        """Close the journal; one that holds no reading is removed (it records nothing a
        rerun needs, and would tie the output file to its plan: a run whose port would
        not open refused the next run's other settings)."""
        if not self.readings and not self._handle.closed:
            self.path.unlink(missing_ok=True)
        self._handle.close()


def _differences(old, new) -> str:
    """The names of the settings that two plans' dicts (an adaptive run's nested one level,
    ``{"adaptive": {...}}``) hold with different values: ``"incidence, seed"``."""
    def flat(plan):
        settings = {}
        for key, part in (plan if isinstance(plan, dict) else {}).items():
            settings.update(part if isinstance(part, dict) else {key: part})
        return settings

    old, new = flat(old), flat(new)
    return ", ".join(sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k)))


def measure(port: str, plan: Plan, out, *, journal=None, reference_reflectance: float = 0.99,
            baud: int = 115200, timeout: float = 1.0, retries: int = 5,
            metadata: dict | None = None, progress: bool = True) -> MeasureResult:
    """Measure a plan on the instrument at ``port`` and write the result to ``out``.

    Args:
        port: the instrument's serial device.
        plan: what to measure.
        out: the measurement file to write (``.csv`` or ``.bsdf``).
        journal: the journal file (default: ``out`` with the suffix ``.journal.jsonl``).
        reference_reflectance: ``rho_ref`` of the PTFE plate at the wavelength, Eq. (8).
        baud, timeout, retries: the driver's settings (`brdfjax.instrument.driver`).
        metadata: extra ``key: value`` lines for the file (``sample`` names it; by default
            the name of ``out`` without its suffix).
        progress: show a progress bar with an ETA (on stderr).

    Returns:
        A `MeasureResult`.

    Raises:
        brdfjax.instrument.driver.InstrumentError: the instrument failed (after retries);
            every reading taken so far is in the journal.
        ValueError: the plan leaves the motors' ranges (raised before anything moves).
    """
    check_reference(reference_reflectance)
    journal_path = Path(out).with_suffix(".journal.jsonl") if journal is None else journal
    record = Journal(journal_path, plan)
    try:
        resumed = len(record.readings)
        todo = [(p, t) for p in plan.points for t in TARGETS
                if (p.index, t) not in record.readings]
        resends = _acquire(port, plan, todo, record, baud=baud, timeout=timeout,
                           retries=retries, progress=progress) if todo else 0
        data = to_measurements(plan, record.readings, reference_reflectance, file_metadata(
            out, record, reference_reflectance, metadata))
    finally:
        record.close()
    from brdfjax.data.formats import save

    save(data, out)
    return MeasureResult(data, len(todo), resumed, resends, Path(journal_path))


def check_reference(reference_reflectance: float) -> None:
    """Refuse a reference plate's reflectance outside (0, 1]."""
    if not 0 < reference_reflectance <= 1:
        raise ValueError(f"reference reflectance {reference_reflectance} not in (0, 1]")


def file_metadata(out, record: Journal, reference_reflectance: float,
                  metadata: dict | None, method: str = "") -> dict:
    """The measurement file's metadata: ``sample`` (by default the name of ``out``), the
    instrument's identity and wavelength, the method and the journal."""
    return {"sample": Path(out).stem, **(metadata or {}),
            "wavelength_nm": f"{record.instrument.get('wavelength_nm', math.nan):g}",
            "instrument": " ".join(str(record.instrument.get(k, "?"))
                                   for k in ("model", "serial", "firmware")),
            "reference_reflectance": reference_reflectance,
            "method": "reference-sample method, Eq. (7)-(8); sigma from the spread of the "
                      f"integrations{method}",
            "journal": str(record.path)}


def _acquire(port, plan: Plan, todo, record: Journal, *, baud, timeout, retries,
             progress) -> int:
    """Read every (point, target) of ``todo``, journaling each; return the resends."""
    from tqdm import tqdm

    with connected(port, record, plan, baud=baud, timeout=timeout,
                   retries=retries) as session:
        total = len(plan.points)
        with tqdm(total=total, initial=total - len(_by_point(todo)), unit="geometry",
                  desc="measure", disable=not progress, dynamic_ncols=True) as bar:
            session.read(plan, todo, record, lambda: bar.update(1))
        return session.instrument.resends


@contextmanager
def connected(port, record: Journal, plan: Plan, *, baud, timeout, retries):
    """An open, identified and homed instrument at ``port`` (its identity journaled), as a
    `Session`; `ValueError` before any motor moves if ``plan`` leaves the motors' ranges
    the instrument reports."""
    from brdfjax.instrument.driver import Instrument

    with Instrument(port, baud=baud, timeout=timeout, retries=retries) as instrument:
        identity = instrument.identify()
        plan.check_limits({m: instrument.limits(m) for m in "ABC"})
        record.append({"kind": "instrument", "instrument": identity})
        instrument.home()
        yield Session(instrument)


class Session:
    """A connected instrument and where its motors and sample changer stand, so that a
    reading moves only what it must."""

    def __init__(self, instrument):
        self.instrument = instrument
        self.position = dict.fromkeys("ABC", 0.0)  # homed
        self.in_beam = None

    def read(self, plan: Plan, todo, record: Journal, point_done=lambda: None) -> None:
        """Read every (point, target) of ``todo`` in order, journaling each with the
        instrument seconds it took (motors, changer, integrations); ``point_done()`` after
        each point's readings."""
        for point, pair in _by_point(todo):
            tic = time.monotonic()
            for motor in "BAC":  # the source first: the detector sweeps last
                wanted = getattr(point, motor.lower())
                if self.position[motor] != wanted:
                    self.instrument.move(motor, wanted)
                    self.position[motor] = wanted
            if self.in_beam in pair and pair[0] != self.in_beam:  # what is in the beam first
                pair = pair[::-1]
            for target in pair:
                if target != self.in_beam:
                    self.instrument.select(target.upper())
                    self.in_beam = target
                reading = self.instrument.read(plan.average, plan.integration_ms)
                toc = time.monotonic()
                record.append({"kind": "reading", "point": point.index, "target": target,
                               "a": point.a, "b": point.b, "c": point.c,
                               "volts": reading.volts, "std": reading.std,
                               "count": reading.count, "seconds": round(toc - tic, 4)})
                tic = toc
            point_done()


def _by_point(todo):
    """``[(point, target), ...]`` grouped as ``[(point, (target, ...)), ...]`` in order."""
    grouped = {}
    for point, target in todo:
        grouped.setdefault(point, []).append(target)
    return [(point, tuple(targets)) for point, targets in grouped.items()]


def to_measurements(plan: Plan, readings: dict, reference_reflectance: float,
                    metadata: dict) -> Measurements:
    """BRDF from paired sample and reference voltages by Eq. (7)-(8).

    Args:
        plan: the plan measured.
        readings: ``{(point index, "sample" | "reference"): {"volts", "std", "count"}}``
            for every point of the plan.
        reference_reflectance: ``rho_ref`` of the reference plate.
        metadata: the file's metadata.

    Returns:
        `Measurements` with ``sigma`` when every reading averaged two or more integrations.
    """
    angles, brdf, relative = [], [], []
    for point in plan.points:
        sample, reference = (readings[(point.index, t)] for t in TARGETS)
        if not reference["volts"] > 0:
            raise DataError(f"reference reading {reference['volts']} V at point "
                            f"{point.index} (A, B, C = {point.a:g}, {point.b:g}, {point.c:g} "
                            "deg) is not positive: is the reference plate in place?")
        angles.append(point.angles)
        brdf.append(sample["volts"] / reference["volts"] * reference_reflectance / math.pi)
        relative.append(math.hypot(*(r["std"] / math.sqrt(r["count"]) / r["volts"]
                                     for r in (sample, reference)))
                        if min(sample["count"], reference["count"]) > 1 else math.nan)
    brdf = np.array(brdf)
    sigma = np.abs(brdf) * np.array(relative)
    theta_i, theta_r, phi_r = np.array(angles).T
    return Measurements.from_degrees(theta_i, theta_r, phi_r, brdf,
                                     sigma=None if np.isnan(sigma).any() else sigma,
                                     metadata=metadata)
