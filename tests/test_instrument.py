"""The instrument: protocol framing, plans, Eq. (7)-(8), the journal, and, through real
pseudo-terminals with the simulator in its own process, measure -> fit, faults, resume and
bad configuration."""

import json
import math
import select
import subprocess
import sys

import numpy as np
import pytest
import serial
from conftest import interruptible

from brdfjax.cli import build_parser, main
from brdfjax.commands.instrument import scan_plan
from brdfjax.data.formats import load
from brdfjax.data.measurements import DataError, Measurements, geometry_keys
from brdfjax.instrument import protocol
from brdfjax.instrument.acquire import Journal, measure, to_measurements
from brdfjax.instrument.design import instrument_grid, plan
from brdfjax.instrument.driver import DisconnectedError, Instrument, RefusedError
from brdfjax.instrument.plan import Plan, load_plan
from brdfjax.instrument.simulator import DataSample, NoData
from brdfjax.models.paper import PAPER_SAMPLES

TRUTH = PAPER_SAMPLES["khaki_paint"]
SEED = 1
# Motors fast and the changer instant, so a plan takes seconds; 1 ms integrations at 0.3 %
# relative noise per 10 ms are ~1 % per integration, ~0.4 % per reading of 5.
SIMULATOR = ["--params", ",".join(map(str, TRUTH)), "--seed", str(SEED), "--noise", "0.003",
             "--motor-speed", "10000", "--changer-seconds", "0"]
PLAN = Plan(incidence=(10, 30, 50), theta_r=(-85, 85, 5), average=5, integration_ms=1)
SCAN = ["--theta-r-step", "5", "--average", "5", "--integration-ms", "1", "--quiet"]
PLAN_OPTIONS = ["--incidence", "10,30,50", *SCAN]  # PLAN, as options of brdfjax measure


# ---------------------------------------------------------------- protocol, plan, Eq. (7)-(8)

def test_frame_round_trip_and_crc():
    assert protocol.checksum(b"123456789") == "29B1"  # the CRC-16/CCITT-FALSE check value
    line = protocol.encode(42, "MOVE", "C", "-12.5")
    assert line == b"42 MOVE C -12.5*" + protocol.checksum(b"42 MOVE C -12.5").encode() + b"\n"
    assert protocol.decode(line) == protocol.Message(42, "MOVE", ("C", "-12.5"))
    assert protocol.decode(protocol.encode(3, "ERR", "RANGE", "a*b")).args == ("RANGE", "a?b")


def test_every_dropped_or_replaced_byte_is_caught():
    line = protocol.encode(1234, "OK", "1.234567890e-01", "2.0e-03", "5")
    for k in range(len(line)):
        with pytest.raises(protocol.FrameError):
            protocol.decode(line[:k] + line[k + 1:])
        for replacement in b"0123456789ABCDEF *OKR\xff":
            if replacement != line[k]:
                with pytest.raises(protocol.FrameError):
                    protocol.decode(line[:k] + bytes([replacement]) + line[k + 1:])


def test_in_plane_plan_skips_the_beam_crossing():
    plan = Plan(incidence=(10, 30), theta_r=(-85, 85, 5))
    for incidence in (10, 30):
        signed = [p.c for p in plan.points if p.b == incidence]
        assert sorted(signed) == [c for c in range(-85, 90, 5) if c != -incidence]
    assert plan.blocked == 2
    first = plan.points[0]
    assert first.angles == (10, 85, 0)  # negative C: the source side, phi_r = 0
    assert plan.points[20].angles == (10, 20, 180)
    # The sweeps alternate direction, so the detector does not travel back.
    assert [p.c for p in plan.points[33:35]] == [85, 85]


def test_plan_with_azimuths_measures_the_normal_once():
    plan = Plan(incidence=(40,), theta_r=(-10, 10, 10), azimuth=(0, 90))
    assert [p.angles for p in plan.points] == [
        (40, 10, 0), (40, 0, 0), (40, 10, 180), (40, 10, 270), (40, 10, 90)]


def test_plan_file_and_its_errors(tmp_path):
    path = tmp_path / "plan.toml"
    path.write_text("incidence = [10, 30]\ntheta_r = [-80, 80, 2]\naverage = 3\n")
    assert load_plan(path) == Plan(incidence=(10, 30), theta_r=(-80, 80, 2), average=3)
    path.write_text("incidence = [10]\ntheta_step = 2\n")
    with pytest.raises(DataError, match="unknown plan key.*theta_step"):
        load_plan(path)
    path.write_text("incidence = [10]\ntheta_r = [80, -80, 2]\n")
    with pytest.raises(DataError, match="start <= stop"):
        load_plan(path)
    with pytest.raises(ValueError, match=r"motor B \(source arm.*85 deg.*0 to 80"):
        Plan(incidence=(30, 85)).check_limits({"A": (0, 180), "B": (0, 80), "C": (-87, 87)})


def test_plan_file_of_listed_geometries_and_its_errors(tmp_path):
    """`brdfjax plan`'s TOML: plan -> file -> reader gives the same geometries in order;
    one past the motor limits, in the beam or repeated is refused naming the entry."""
    design = plan(None, instrument_grid(out_of_plane=True), 12, seed=2)
    path = tmp_path / "next.toml"
    path.write_text(design.instrument_plan().to_toml("written by a test"))
    listed = load_plan(path)
    assert listed == design.instrument_plan() and listed.blocked == 0
    measured_at = np.array([p.angles for p in listed.points]).T
    assert np.array_equal(geometry_keys(*measured_at),
                          geometry_keys(design.theta_i, design.theta_r, design.phi_r))
    assert json.loads(json.dumps(listed.to_dict())) == listed.to_dict()  # as the journal keeps it
    for text, message in [
        ("geometries = [[10, 20, 180], [85, 20, 180]]\n",
         (r"next.toml: measurement plan: geometries\[1\] = \[85, 20, 180\]: needs motor B "
          r"\(source arm \(incidence\)\) at 85 deg, outside its range 0 to 80 deg")),
        ("geometries = [[10, 20, 180], [30, 89, 0]]\n", r"geometries\[1\] = .*motor C"),
        ("geometries = [[30, 31, 0]]\n",
         r"geometries\[0\] = \[30, 31, 0\]: the detector would be 1 deg from the source"),
        ("geometries = [[30, 0, 0], [30, 0, 90]]\n",
         r"geometries\[1\] = .*the same geometry as geometries\[0\]"),
        ("geometries = [[30, 20]]\n", r"geometries\[0\] = \[30, 20\]: give \[theta_i"),
        ("incidence = [10]\ngeometries = [[30, 20, 0]]\n",
         "lists geometries and also has incidence"),
    ]:
        path.write_text(text)
        with pytest.raises(DataError, match=message):
            load_plan(path)
    narrower = {"A": (0, 180), "B": (0, 50), "C": (-87, 87)}
    with pytest.raises(ValueError, match=r"geometries\[1\] = \[60, 20, 180\]: .*0 to 50"):
        Plan(geometries=((10, 20, 180), (60, 20, 180))).check_limits(narrower)


def test_measure_options_make_the_plan(tmp_path):
    path = tmp_path / "plan.toml"
    path.write_text("incidence = [10, 30]\ntheta_r = [-80, 80, 2]\n")
    parse = build_parser().parse_args
    common = ["measure", "--port", "/dev/null", "--out", "x.csv"]
    assert scan_plan(parse([*common, "--plan", str(path)])) == load_plan(path)
    assert scan_plan(parse([*common, "--incidence", "10,30", "--theta-r-step", "5",
                            "--theta-r-max", "60"])) == Plan((10, 30), (-60, 60, 5))
    with pytest.raises(ValueError, match="put --average in the plan file"):
        scan_plan(parse([*common, "--plan", str(path), "--average", "3"]))


def test_reference_sample_method():
    plan = Plan(incidence=(30,), theta_r=(20, 20, 1))
    readings = {(0, "sample"): {"volts": 0.5, "std": 0.01, "count": 4},
                (0, "reference"): {"volts": 0.25, "std": 0.005, "count": 4}}
    data = to_measurements(plan, readings, 0.98, {})
    f = 0.5 / 0.25 * 0.98 / math.pi  # Eq. (8)
    assert data.brdf[0] == pytest.approx(f)
    assert data.sigma[0] == pytest.approx(f * math.hypot(0.01 / 2 / 0.5, 0.005 / 2 / 0.25))
    assert np.degrees([data.theta_i[0], data.theta_r[0], data.phi_r[0]]) == pytest.approx(
        [30, 20, 180])


def test_journal_drops_a_cut_short_line_and_refuses_another_plan(tmp_path):
    plan, path = Plan(incidence=(30,), theta_r=(0, 10, 10)), tmp_path / "j.jsonl"
    journal = Journal(path, plan)
    journal.append({"kind": "reading", "point": 0, "target": "sample", "volts": 1.0,
                    "std": 0.0, "count": 1})
    journal.close()
    with open(path, "a") as handle:
        handle.write('{"kind": "reading", "point": 0, "targ')  # killed mid-write
    journal = Journal(path, plan)
    assert list(journal.readings) == [(0, "sample")]
    journal.append({"kind": "reading", "point": 0, "target": "reference", "volts": 1.0,
                    "std": 0.0, "count": 1})
    journal.close()
    assert [json.loads(line)["kind"] for line in path.read_text().splitlines()] == [
        "plan", "reading", "reading"]
    kept = path.read_text()
    with pytest.raises(DataError, match="another plan.*its plan differs from this run's in incidence;"):
        Journal(path, Plan(incidence=(40,), theta_r=(0, 10, 10)))
    assert path.read_text() == kept  # a refused journal is left as it was, readings and all
    other = tmp_path / "notes.txt"
    other.write_text("not a journal\n")
    with pytest.raises(DataError, match="not a JSON line"):
        Journal(other, plan)
    assert other.read_text() == "not a journal\n"
    journal = Journal(path, plan)
    with pytest.raises(DataError, match="in use by another acquisition"):
        Journal(path, plan)
    journal.close()


def test_data_sample_interpolates_between_measurements():
    signed = np.array([-40.0, 0.0, 40.0])
    data = Measurements.from_degrees(
        np.repeat([20.0, 40.0], 3), np.tile(np.abs(signed), 2),
        np.tile(np.where(signed > 0, 180.0, 0.0), 2), [1.0, 2.0, 3.0, 5.0, 6.0, 7.0])
    sample = DataSample(data)
    assert sample.brdf(20, 40, 180) == 3.0
    assert sample.brdf(20, 20, 0) == 1.5  # halfway along the 20 deg curve
    assert sample.brdf(30, 0, 0) == 4.0  # halfway between the incidences
    with pytest.raises(NoData, match="outside the data"):
        sample.brdf(50, 0, 0)
    with pytest.raises(NoData, match="off the plane"):
        sample.brdf(30, 10, 90)


# ---------------------------------------------------------------- through a pseudo-terminal

@pytest.fixture(scope="module")
def simulator():
    """Start simulators (``brdfjax instrument simulate``, each its own process); all are
    killed when the module's tests are done."""
    processes = []

    def start(*options):
        process = subprocess.Popen(
            [sys.executable, "-m", "brdfjax.cli", "instrument", "simulate", *SIMULATOR,
             *options], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        processes.append(process)
        ready, _, _ = select.select([process.stdout], [], [], 60)
        port = process.stdout.readline().strip() if ready else ""
        if not port.startswith("/dev/"):
            process.kill()
            pytest.fail(f"the simulator printed no device path: {process.communicate()}")
        return process, port

    yield start
    for process in processes:
        process.kill()
        process.wait()


@pytest.fixture(scope="module")
def clean_run(simulator, tmp_path_factory):
    """The plan measured on a fault-free simulator: the reference for the other runs."""
    _, port = simulator()
    out = tmp_path_factory.mktemp("clean") / "clean.csv"
    result = measure(port, PLAN, out, progress=False)
    assert result.read_now == 2 * len(PLAN.points) and result.resends == 0
    data = load(out)
    assert data.metadata["sample"] == "clean"  # named for its file, not "sample"
    return out, data


def same_readings(a: Measurements, b: Measurements) -> bool:
    return all(np.array_equal(getattr(a, k), getattr(b, k))
               for k in ("theta_i", "theta_r", "phi_r", "brdf", "sigma"))


def test_measure_then_fit_recovers_the_simulated_parameters(clean_run, tmp_path):
    path, data = clean_run
    assert len(data) == len(PLAN.points) == 102
    assert main(["fit", str(path), "--uncertainty", "laplace",
                 "--json", str(tmp_path / "fit.json")]) == 0
    record = json.loads((tmp_path / "fit.json").read_text())
    uncertainty = record["uncertainty"]
    assert uncertainty["status"] == "ok", uncertainty["warnings"]
    for name, true in TRUTH._asdict().items():
        reported = uncertainty["params"][name]
        low, high = reported["ci95"]
        print(f"{name}: true {true:g}, fit {record['params'][name]:.5g}, Laplace "
              f"{reported['median']:.5g} +- {reported['std']:.2g}, 95 % [{low:.5g}, {high:.5g}]")
        assert low <= true <= high
        assert abs(record["params"][name] - true) < 3 * reported["std"]  # the Eq. (6) fit
        assert reported["std"] < 0.1 * abs(true)  # and the data do pin it down


@pytest.mark.timeout(300)
def test_faults_on_the_line_do_not_change_the_data(simulator, clean_run, tmp_path):
    _, port = simulator("--drop-rate", "0.05", "--corrupt-rate", "0.05", "--stall-rate",
                        "0.01", "--stall-seconds", "0.4")
    result = measure(port, PLAN, tmp_path / "faulty.csv", timeout=0.25, retries=8,
                     progress=False)
    print("resends", result.resends)
    assert result.resends > 20  # the faults did happen...
    assert same_readings(load(tmp_path / "faulty.csv"), clean_run[1])  # ...changed nothing


@pytest.mark.timeout(300)
def test_a_disconnected_run_resumes_from_its_journal(simulator, clean_run, tmp_path, capsys):
    out, journal = tmp_path / "resumed.csv", tmp_path / "resumed.journal.jsonl"
    first, port = simulator("--disconnect-after", "200")
    assert main(["measure", "--port", port, "--out", str(out), *PLAN_OPTIONS]) == 1
    assert "lost the instrument" in capsys.readouterr().err
    first.wait(timeout=10)
    taken = sum(json.loads(line)["kind"] == "reading" for line in journal.open())
    assert 0 < taken < 2 * len(PLAN.points)
    assert not out.exists()

    _, port = simulator()
    assert main(["measure", "--port", port, "--out", str(out), *PLAN_OPTIONS]) == 0
    with Instrument(port) as instrument:
        assert int(instrument.status()["reads"]) == 2 * len(PLAN.points) - taken
    readings = [(r["point"], r["target"]) for r in map(json.loads, journal.open())
                if r["kind"] == "reading"]
    assert sorted(readings) == sorted((p.index, t) for p in PLAN.points
                                      for t in ("sample", "reference"))
    resumed = load(out)
    assert same_readings(resumed, clean_run[1])
    # No --sample: the file is named for --out (resumed.csv), not "# sample: sample".
    assert resumed.metadata["sample"] == "resumed"
    assert "# sample: resumed\n" in out.read_text()


@pytest.mark.timeout(120)
def test_bad_configuration_fails_before_any_motor_moves(simulator, tmp_path, capsys):
    out = str(tmp_path / "never.csv")
    assert main(["measure", "--port", "/dev/no-such-port", "--out", out, *PLAN_OPTIONS]) == 1
    assert "cannot open the instrument's port /dev/no-such-port" in capsys.readouterr().err
    # A journal without a reading is not kept: it tied the file to the plan of a run that
    # never started, and refused the next run's other settings.
    assert not (tmp_path / "never.journal.jsonl").exists()

    _, port = simulator()
    assert main(["measure", "--port", port, "--baud", "9600", "--timeout", "0.3",
                 "--out", out, *PLAN_OPTIONS]) == 1
    message = capsys.readouterr().err
    assert "9600 baud" in message and "wrong baud rate" in message

    assert main(["measure", "--port", port, "--out", out, "--journal",
                 str(tmp_path / "j2.jsonl"), "--incidence", "30,85", *SCAN]) == 1
    assert "motor B (source arm (incidence)) at 85 deg" in capsys.readouterr().err

    with Instrument(port) as instrument:
        status = instrument.status()
        assert (status["moves"], status["reads"], status["homed"]) == ("0", "0", "0")
        with pytest.raises(RefusedError, match="NOTHOMED"):
            instrument.move("C", 10)
        instrument.home()
        with pytest.raises(RefusedError, match="RANGE") as refused:
            instrument.move("B", 85)
        assert refused.value.code == "RANGE"


@pytest.mark.timeout(120)
def test_a_repeated_command_runs_once_and_a_killed_simulator_is_reported(simulator):
    process, port = simulator("--motor-speed", "100")
    with serial.Serial(port, 115200, timeout=2) as line:

        def send(seq, word, *args):
            line.write(protocol.encode(seq, word, *args))

        def reply():
            return protocol.decode(line.readline())

        send(1, "HOME")
        assert reply() == protocol.Message(1, "OK")
        send(2, "MOVE", "C", "20")  # 0.2 s of travel
        send(2, "MOVE", "C", "20")  # a retry while it runs
        assert [reply().word, reply().word, reply()] == [
            "BUSY", "BUSY", protocol.Message(2, "OK", ("C", "20.00"))]
        send(2, "MOVE", "C", "20")  # a retry after it finished: the same reply again
        assert reply() == protocol.Message(2, "OK", ("C", "20.00"))
        line.write(b"3 STATUS?*0000\n")  # a damaged line gets a NAK
        assert reply() == protocol.Message(0, "ERR", ("CHECKSUM", "checksum", "'0000'", "does",
                                                      "not", "match", "the", "line"))
        send(3, "STATUS?")
        assert "moves=2" in reply().args  # HOME and one MOVE
    with Instrument(port, timeout=0.5) as instrument:
        assert instrument.position("C") == 20
        process.kill()
        process.wait()
        with pytest.raises(DisconnectedError, match="lost the instrument"):
            instrument.position("C")


@pytest.mark.timeout(120)
def test_measure_visits_the_listed_geometries_in_order(simulator, tmp_path):
    _, port = simulator()
    listed = Plan(geometries=((50, 30, 180), (10, 40, 0), (10, 0, 0), (30, 25, 90),
                              (30, 60, 300)), average=2, integration_ms=1)
    result = measure(port, listed, tmp_path / "listed.csv", progress=False)
    assert result.read_now == 10
    data = load(tmp_path / "listed.csv")
    assert np.array_equal(data.geometries(), geometry_keys(*np.array(listed.geometries).T))



# ---------------------------------------------------------------- measure --adaptive

REGION = ["--incidence", "10,30,50,70", "--theta-r-step", "5", "--average", "2",
          "--integration-ms", "1"]
# A start large enough for the first round to calibrate (its two interior incidences hold
# the 19 held-out scores a finite 95 % factor needs), and batches of 12, so that two
# checked batches calibrate the third round: the fewest rounds that can stop on the width.
START, BATCH = 40, 12
ADAPTIVE = ["--adaptive", "--target-width", "8", "--start", str(START), "--batch", str(BATCH),
            "--quiet"]


def journal_records(path, kind):
    """The journal's records of ``kind``; a last line still being written (a running
    measurement's, read while it writes) is not a record yet."""
    with open(path) as lines:
        written = [line for line in lines if line.endswith("\n")]
    return [r for r in map(json.loads, written) if r["kind"] == kind]


@pytest.fixture(scope="module")
def adaptive_run(simulator, tmp_path_factory):
    """``measure --adaptive`` run to its stop on a fault-free simulator: (out, journal, the
    region's plan)."""
    _, port = simulator()
    out = tmp_path_factory.mktemp("adaptive") / "khaki.csv"
    assert main(["measure", "--port", port, "--out", str(out), *REGION, *ADAPTIVE]) == 0
    return out, out.with_suffix(".journal.jsonl"), scan_plan(build_parser().parse_args(
        ["measure", "--port", port, "--out", str(out), *REGION]))


@pytest.mark.timeout(500)
def test_adaptive_measurement_stops_honestly_and_resumes_with_the_same_decisions(
        simulator, adaptive_run, tmp_path, capsys):
    """One test of the clean run (`adaptive_run`): xdist would make the module's fixture
    again on every worker that runs a test using it."""
    stops_on_the_width_with_honest_intervals(*adaptive_run)
    interrupted_resumes_with_the_same_decisions(simulator, *adaptive_run[:2], tmp_path)
    resumed_with_a_lower_cap_reports_the_round_it_stopped_at(simulator, adaptive_run[1],
                                                            tmp_path, capsys)


def stops_on_the_width_with_honest_intervals(out, journal, region):
    from brdfjax import brdf, predict
    from brdfjax.instrument.adaptive import BATCH_SCORES, calibrated, fitted

    data = load(out)
    rounds = journal_records(journal, "round")
    # It stopped on the target, once the newest batch also fell inside the last intervals
    # and the batches' own scores calibrated them...
    assert rounds[-1]["half_width"] <= 0.08 and rounds[-1]["checked"] >= 0.9
    assert rounds[-1]["by_batches"]
    assert all(r["half_width"] is None or r["half_width"] > 0.08 or r["checked"] is None
               or r["checked"] < 0.9 or not r["by_batches"] for r in rounds[:-1])
    assert rounds[0]["checked"] is None and rounds[0]["scores"] is None
    scored = [r["scores"] for r in rounds if r["scores"]]
    assert all(len(s["sigma"]) == len(s["relative"]) == BATCH for s in scored)  # each reading
    counts = np.cumsum([0 if r["scores"] is None else BATCH for r in rounds])
    assert [r["by_batches"] for r in rounds] == list(counts >= BATCH_SCORES)
    assert len(data) == rounds[-1]["readings"] < len(region.points)  # ...before the grid
    assert [r["readings"] for r in rounds] == list(range(START, len(data) + 1, BATCH))
    assert out.with_suffix(".adaptive.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # Every reading was read where a batch said, each geometry once, and the geometries
    # are the region's.
    listed = np.concatenate([b["geometries"] for b in journal_records(journal, "batch")])
    assert np.array_equal(data.geometries(), geometry_keys(*listed.T))
    grid = {tuple(k) for k in geometry_keys(*np.array([p.angles for p in region.points]).T)}
    assert {tuple(k) for k in data.geometries()} <= grid
    # The intervals over the readings it did not take hold the true BRDF (the paper's
    # model at the simulated khaki paint, not what the loop fitted).
    left = np.array([p.angles for p in region.points
                     if tuple(geometry_keys(*p.angles)[0]) not in
                     {tuple(k) for k in data.geometries()}])
    ti, tr, pr = np.radians(left.T)
    truth = np.asarray(brdf(TRUTH, ti, tr, pr))
    _, result = fitted(data, "ggx", 0)  # the last round's intervals, as the stop measured
    calibration, by_batches = calibrated(result, 0, scored)
    assert by_batches
    prediction = predict(result, Measurements(ti, tr, pr, truth), calibration)
    print(f"{len(data)} of {len(region.points)} read; coverage of the rest "
          f"{prediction.coverage():.3f}, median half-width "
          f"{np.median(prediction.half_width()):.4f}")
    assert 0.90 <= prediction.coverage() <= 1.0
    assert np.median(prediction.half_width()) <= 0.08


def interrupted_resumes_with_the_same_decisions(simulator, clean_out, clean_journal, tmp_path):
    import signal
    import time

    out = tmp_path / "khaki.csv"
    journal = out.with_suffix(".journal.jsonl")
    _, port = simulator()
    command = [sys.executable, "-m", "brdfjax.cli", "measure", "--port", port, "--out",
               str(out), *REGION, *ADAPTIVE]
    process = interruptible(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    deadline = time.monotonic() + 200
    # Interrupted once the start is read: three rounds at least are left (the first has no
    # batch to check its intervals, the second too few scores), so it is fitting or
    # reading, never done (a fixed wait after it let a warm run finish first).
    while time.monotonic() < deadline and process.poll() is None:
        if journal.exists() and len(journal_records(journal, "reading")) >= 2 * START:
            break
        time.sleep(0.02)
    process.send_signal(signal.SIGINT)
    tic = time.monotonic()
    _, err = process.communicate(timeout=30)
    assert process.returncode == 130, err
    assert time.monotonic() - tic < 2.0
    assert not out.exists()
    taken = len(journal_records(journal, "reading"))
    assert taken >= 2 * START

    _, port = simulator()
    assert main(["measure", "--port", port, "--out", str(out), *REGION, *ADAPTIVE]) == 0
    with Instrument(port) as instrument:  # nothing read twice
        assert int(instrument.status()["reads"]) == len(journal_records(journal, "reading")) \
            - taken
    strip = [{k: v for k, v in r.items() if k != "time"} for r in
             journal_records(journal, "batch")]
    assert strip == [{k: v for k, v in r.items() if k != "time"}
                     for r in journal_records(clean_journal, "batch")]
    assert same_readings(load(out), load(clean_out))
    # ...and the same rounds: widths, checks and the batches' scores (minutes are wall time)
    for resumed, clean in zip(*(journal_records(j, "round") for j in (journal, clean_journal)),
                              strict=True):
        for key in ("readings", "model", "by_batches"):
            assert resumed[key] == clean[key], key
        numbers = [(key, resumed[key], clean[key]) for key in ("half_width", "checked")]
        numbers += [(form, (resumed["scores"] or {}).get(form), (clean["scores"] or {}).get(form))
                    for form in ("sigma", "relative")]
        for key, found, expected in numbers:
            assert (found is None) == (expected is None), key
            if expected is not None:
                np.testing.assert_allclose(found, expected, rtol=1e-6, err_msg=key)


def resumed_with_a_lower_cap_reports_the_round_it_stopped_at(simulator, clean_journal,
                                                            tmp_path, capsys):
    """The finished run resumed with --max-readings at its second round stops there, reads
    nothing, and reports that round (it reported the journal's last: its width, for
    readings it did not keep)."""
    import shutil

    out = tmp_path / "capped.csv"
    shutil.copy(clean_journal, out.with_suffix(".journal.jsonl"))
    second = journal_records(clean_journal, "round")[1]
    _, port = simulator()
    capsys.readouterr()
    assert main(["measure", "--port", port, "--out", str(out), *REGION, *ADAPTIVE,
                 "--max-readings", str(START + BATCH)]) == 0
    said = capsys.readouterr().out
    assert len(load(out)) == START + BATCH == second["readings"]
    assert "adaptive: stopped after 2 round(s)" in said
    width = second["half_width"]
    assert ("median 95 % half-width over the region "
            + ("none yet" if width is None else f"{100 * width:.3g} %")) in said


def test_adaptive_stop_rule():
    from brdfjax.instrument.adaptive import Round, _stop, levelled

    def rounds(widths, checked=1.0, minutes=0.0, by_batches=True):
        return [Round(20 + 10 * k, minutes, "ggx", w, None if k == 0 else checked,
                      by_batches=by_batches) for k, w in enumerate(widths)]

    def stop(history, readings=50, candidates=100, max_readings=None, max_minutes=None):
        return _stop(history, readings, candidates, 0.10, max_readings, max_minutes)

    assert stop(rounds([math.inf, 0.08])) == "target"
    assert stop(rounds([math.inf, 0.08], checked=0.8)) is None  # the newest batch missed
    # calibrated by the held-out incidences alone: not trusted to stop on
    assert stop(rounds([math.inf, 0.08], by_batches=False)) is None
    assert stop(rounds([0.08])) is None  # no batch has checked the intervals yet
    # Five calibrated rounds, none 5 % below the narrowest before them: levelled off.
    flat = [math.inf, 0.31, 0.33, 0.30, 0.35, 0.32, 0.31]
    assert levelled(rounds(flat)) and stop(rounds(flat)) == "levelled"
    assert not levelled(rounds(flat[:-1]))  # only 4 rounds after the first calibrated one
    assert not levelled(rounds([*flat[:-1], 0.29]))  # 0.29 < 0.95 x 0.31: still narrowing
    assert stop(rounds([math.inf]), readings=30, max_readings=30) == "max-readings"
    assert stop(rounds([math.inf], minutes=12.0), max_minutes=10) == "max-minutes"
    assert stop(rounds([math.inf]), readings=100) == "candidates"
    assert stop(rounds([math.inf]), max_readings=60, max_minutes=13) is None


def test_adaptive_batches_calibrate_once_they_hold_enough_scores():
    from types import SimpleNamespace

    from brdfjax.instrument.adaptive import BATCH_SCORES, calibrated
    from brdfjax.prediction.intervals import Calibration

    held_out = Calibration(interior=np.linspace(0.1, 3.0, 30), every=np.linspace(0.1, 4.0, 60),
                           floor=0.01, low=10.0, high=70.0, score="sigma")
    result = SimpleNamespace(calibrations={("gp", 0): held_out})
    narrow = list(np.linspace(0.05, 0.5, 10))
    wide = list(5 * np.asarray(narrow))

    def factor(*scored):
        calibration, by_batches = calibrated(result, 0, list(scored))
        return calibration.factor(0.95, False), calibration.factor(0.95, True), by_batches

    assert BATCH_SCORES == 19  # the fewest n with ceil((n + 1) 0.95) <= n
    # one batch of 10: the held-out incidences still calibrate
    assert factor({"sigma": narrow, "relative": wide}) == (
        held_out.factor(0.95, False), held_out.factor(0.95, True), False)
    # two: their scores in the calibration's form alone set the factor inside the measured
    # incidences, narrower than the held-out one here; extrapolation keeps the held-out one
    inside, outside, by_batches = factor(*[{"sigma": narrow, "relative": wide}] * 2)
    assert by_batches and inside == 0.5 < held_out.factor(0.95, False)
    assert outside == held_out.factor(0.95, True)
    # and wider where the batches missed by more
    assert factor({"sigma": narrow, "relative": narrow}, {"sigma": wide, "relative": narrow}
                  )[0] == 2.5


@pytest.mark.timeout(120)
def test_adaptive_bad_input_fails_before_any_motor_moves(tmp_path, capsys):
    out = str(tmp_path / "never.csv")
    port = ["--port", "/dev/no-such-port", "--out", out]
    cases = {
        ("--target-width", "0"): "--target-width 0 %: give the median 95 % half-width",
        ("--model", "nonesuch"): "--model nonesuch: unknown model",
        ("--start", "4"): "--start 4: ggx has 4 parameters",
        ("--max-readings", "10"): "--max-readings 10: fewer than the 20 readings",
        ("--max-minutes", "-1"): "--max-minutes -1: give a time above 0",
    }
    for options, message in cases.items():
        assert main(["measure", *port, *REGION, "--adaptive", *options]) == 1
        assert message in capsys.readouterr().err, options
    assert main(["measure", *port, *REGION, "--target-width", "5"]) == 1
    assert "--target-width: only with --adaptive" in capsys.readouterr().err
    assert main(["measure", *port, "--incidence", "30,85", "--adaptive"]) == 1
    assert "85 deg" in capsys.readouterr().err
    assert not (tmp_path / "never.journal.jsonl").exists()
    for incidences in ("10,30,50,70", "10,30,50"):  # the second is not refused for the first
        assert main(["measure", *port, *REGION[2:], "--incidence", incidences,
                     "--adaptive"]) == 1
        assert "cannot open the instrument's port" in capsys.readouterr().err
        assert not (tmp_path / "never.journal.jsonl").exists()
