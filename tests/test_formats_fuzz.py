"""Readers never crash: corrupted files of every format give a `DataError` or a valid load.

Each property starts from a valid file of one format and corrupts it: truncation, random
bytes, swapped columns, huge and tiny numbers, deleted sections, wrong counts. The load
must either succeed with data that pass `validate`, or raise `DataError` naming the file
(and, where one is given, a line inside the file), with no NumPy repr in the message.
Deadlines catch hangs.
"""

import re
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from conftest import REAL
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from brdfjax.data.formats import load, load_geometry
from brdfjax.data.measurements import DataError, Measurements, validate

UAZ = REAL / "uaz-loft-rt300s"
SETTINGS = settings(max_examples=60, deadline=5000, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])

CSV = ("# sample: fuzz\n# wavelength_nm: 633\ntheta_i,theta_r,phi_r,brdf,sigma\n"
       + "".join(f"{ti},{tr},{pr},{0.1 + 0.001 * tr},0.005\n"
                 for ti in (10, 40) for tr in (0, 30, 60) for pr in (0, 90, 180)))
NIST = ("lambda,thetai,phii,thetar,phir,fr11,m12\n"
        + "".join(f"{w},-{ti},0,{tr},{pr},0.3,0.01\n"
                  for w in (0.351, 0.633) for ti in (0, 30) for tr in (10, 50)
                  for pr in (0, 90, 180)))
ASTM = ("SOURCE fuzz\nSAMPLE_NAME fuzz\nNUM_POINTS 8\n"
        "VARS theta_i,phi_i,theta_s,phi_s,550nm,650nm\n"
        + "".join(f"{ti},0.5,{ts},{ps},0.2,0.3\n"
                  for ti in (0.2, 0.7) for ts in (0.1, 0.9) for ps in (0.5, 3.6)))
ZEMAX = (UAZ / "processed_by_authors" / "AnoBlackEC1onAlum.bsdf").read_text()
TEXT_FILES = {"fuzz.csv": CSV, "ptfe.csv": NIST, "fuzz.astm": ASTM, "fuzz.bsdf": ZEMAX}
NUMBERS = ["1e308", "-1e308", "1e30", "1e-320", "0", "-0", "nan", "inf", "1e400", "-5",
           "9999999999", "1.5.2", "", "0x1f", "1,5"]


def check_load(path: Path, **options):
    """Load and judge: a validated load, or a DataError that names the file and line."""
    try:
        data = load(path, **options)
    except DataError as error:
        message = str(error)
        assert str(path) in message, message
        assert "np." not in message and "array(" not in message, message
        if error.line is not None:
            raw = path.read_bytes().replace(b"\r\n", b"\n").replace(b"\r", b"\n")
            lines = raw.count(b"\n") + 1
            assert 1 <= error.line <= lines, message
            assert f"{path}:{error.line}:" in message
        return None
    assert isinstance(data, Measurements) and len(data) > 0
    validate(data)
    return data


def written(name: str, content: bytes) -> Path:
    folder = Path(tempfile.mkdtemp(prefix="brdfjax-fuzz-"))
    path = folder / name
    path.write_bytes(content)
    return path


def options_for(name: str) -> dict:
    return {"wavelength_nm": 633} if name == "ptfe.csv" else (
        {"wavelength_nm": 550} if name.endswith(".astm") else {})


names = st.sampled_from(sorted(TEXT_FILES))


@SETTINGS
@given(name=names, fraction=st.floats(0, 1))
def test_truncated(name, fraction):
    content = TEXT_FILES[name].encode()
    check_load(written(name, content[:int(len(content) * fraction)]), **options_for(name))


@SETTINGS
@given(name=names, position=st.floats(0, 1), noise=st.binary(min_size=1, max_size=40))
def test_random_bytes(name, position, noise):
    content = TEXT_FILES[name].encode()
    at = int(len(content) * position)
    check_load(written(name, content[:at] + noise + content[at + len(noise):]),
               **options_for(name))


@SETTINGS
@given(noise=st.binary(max_size=400), name=st.sampled_from(
    ["x.csv", "x.astm", "x.bsdf", "x.txt", "x.xls"]))
def test_pure_noise(noise, name):
    check_load(written(name, noise))


@SETTINGS
@given(name=names, data=st.data())
def test_huge_tiny_and_odd_numbers(name, data):
    text = TEXT_FILES[name]
    tokens = list(re.finditer(r"-?\d+(\.\d+)?(e-?\d+)?", text))
    chosen = data.draw(st.lists(st.sampled_from(tokens), min_size=1, max_size=4,
                                unique_by=lambda m: m.start()))
    for match in sorted(chosen, key=lambda m: -m.start()):
        text = text[:match.start()] + data.draw(st.sampled_from(NUMBERS)) + text[match.end():]
    check_load(written(name, text.encode()), **options_for(name))


@SETTINGS
@given(name=names, data=st.data())
def test_swapped_columns_and_deleted_sections(name, data):
    lines = TEXT_FILES[name].splitlines()
    k = data.draw(st.integers(0, len(lines) - 1))
    separator = "\t" if name.endswith(".bsdf") else ","
    cells = lines[k].split(separator)
    if len(cells) > 1:
        i, j = data.draw(st.integers(0, len(cells) - 1)), data.draw(st.integers(0, len(cells) - 1))
        cells[i], cells[j] = cells[j], cells[i]
        lines[k] = separator.join(cells)
    start = data.draw(st.integers(0, len(lines)))
    stop = data.draw(st.integers(start, min(len(lines), start + 8)))
    del lines[start:stop]
    check_load(written(name, "\n".join(lines).encode()), **options_for(name))


@SETTINGS
@given(keyword=st.sampled_from(["AngleOfIncidence", "ScatterAzimuth", "ScatterRadial",
                                "SampleRotation"]),
       count=st.sampled_from(["0", "1", "3", "11", "13", "20", "-1", "999999999", "x", ""]))
def test_wrong_counts_in_zemax_headers(keyword, count):
    text = re.sub(rf"^{keyword}\t\d+", f"{keyword}\t{count}", ZEMAX, flags=re.MULTILINE)
    check_load(written("counts.bsdf", text.encode()))


@SETTINGS
@given(count=st.sampled_from(["0", "7", "9", "-8", "8.0", "many", ""]))
def test_wrong_counts_in_astm_headers(count):
    check_load(written("counts.astm", ASTM.replace("NUM_POINTS 8", f"NUM_POINTS {count}")
                       .encode()), wavelength_nm=650)


@settings(max_examples=25, deadline=10000, derandomize=True)
@given(fraction=st.floats(0, 1), noise=st.binary(max_size=64), position=st.floats(0, 1))
def test_corrupted_rt300s_workbooks(fraction, noise, position):
    content = (UAZ / "raw" / "NiTE_on_steel_v1o0A_20250915.xls").read_bytes()
    at = int(len(content) * position)
    content = (content[:at] + noise + content[at + len(noise):])[:max(1, int(len(content)
                                                                              * fraction))]
    path = written("sample.xls", content)
    shutil.copy(UAZ / "raw" / "blank_v2o0_20250911.xls", path.parent / "blank_v2o0.xls")
    check_load(path)


@SETTINGS
@given(text=st.text(alphabet=st.sampled_from(list("0123456789.,;\t-e#\n theta_irpb")),
                    max_size=200))
def test_geometry_reader_on_random_text(text):
    path = written("g.csv", text.encode())
    try:
        data = load_geometry(path)
    except DataError as error:
        assert str(path) in str(error) and "np." not in str(error)
    else:
        assert len(data) > 0 and np.all(np.isfinite(data.theta_i))


@pytest.mark.parametrize("value", ["1e308", "1e30", "3e12"])
@pytest.mark.parametrize("name", ["fuzz.csv", "ptfe.csv", "fuzz.astm"])
def test_a_huge_brdf_is_reported_as_an_outlier(value, name):
    text = TEXT_FILES[name]
    target = {"fuzz.csv": "0.13,0.005", "ptfe.csv": "0.3,0.01", "fuzz.astm": "0.2,0.3"}[name]
    replaced = {"fuzz.csv": f"{value},0.005", "ptfe.csv": f"{value},0.01",
                "fuzz.astm": f"{value},{value}"}[name]
    lines = text.splitlines()
    k = max(i for i, line in enumerate(lines) if line.endswith(target))
    lines[k] = lines[k][:-len(target)] + replaced
    path = written(name, "\n".join(lines).encode())
    expected = f"{path.name}:{k + 1}: brdf = {float(value):g} is an outlier: more than 1e8"
    with pytest.raises(DataError, match=re.escape(expected)):
        load(path, **options_for(name))


def spoiled(kind: int, points: int, seed: int) -> Measurements:
    """A plausible sample of ``points`` readings (weighted for odd seeds), with one of
    `validate`'s problems (kind 1-6) or none (kind 0); without readings when ``points`` is 0."""
    rng = np.random.default_rng(seed)
    brdf = rng.uniform(0.01, 1.0, points)
    theta_r = rng.uniform(0, 80, points)
    sigma = 0.02 * brdf if kind == 5 else None
    weights = rng.uniform(0.5, 2.0, points) if seed % 2 or kind == 6 else None
    spot = rng.integers(max(points, 1))
    if points and kind:
        {1: brdf, 2: brdf, 3: brdf, 4: theta_r, 5: sigma, 6: weights}[kind][spot] = {
            1: np.nan, 2: 1e30, 3: -0.5, 4: 95.0, 5: 0.0, 6: -1.0}[kind]
    return Measurements.from_degrees(rng.uniform(0, 70, points), theta_r,
                                     rng.choice([0.0, 180.0], points), brdf, sigma=sigma,
                                     weights=weights, metadata={"sample": f"s{seed}"})


@given(st.lists(st.tuples(st.integers(0, 6), st.sampled_from([0, 3, 4, 5, 8]),
                          st.integers(0, 2**16)), min_size=1, max_size=12))
def test_a_batch_is_checked_as_each_sample_alone(specs):
    """`failures` checks a batch's samples stacked by length: each gets the message
    `validate` gives it alone, whatever the samples beside it hold; a sample without points
    is told so as a sample (a cube's pixel has no lines, unlike a file: issue 47)."""
    from brdfjax.data.measurements import failures

    samples = [spoiled(*spec) for spec in specs]
    expected = {}
    for position, data in enumerate(samples):
        if len(data) == 0:
            expected[position] = (f"{data.name}: the sample has no readings (every reading "
                                  "is NaN or none was given: nothing to fit)")
            continue
        try:
            validate(data, path=data.name)
        except DataError as error:
            expected[position] = str(error)
    assert failures(samples) == expected
    assert {p for p, (kind, points, _) in enumerate(specs) if kind or not points} == set(expected)


def real_files():
    for path in sorted(REAL.rglob("*")):
        if path.suffix in (".xls", ".bsdf", ".csv") and "blank" not in path.name \
                and "derived" not in path.parts:
            yield path


@pytest.mark.parametrize("path", list(real_files()), ids=lambda p: p.name)
def test_every_real_file_loads_and_passes_validation(path):
    if path.name == "PTFE.data.csv":
        for wavelength in (351, 532, 633, 1064):
            validate(load(path, wavelength_nm=wavelength))
    else:
        validate(load(path))
