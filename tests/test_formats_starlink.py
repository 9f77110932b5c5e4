"""The Starlink v1.5 ScatterWorks reader (lumos-sat convention), checked against lines of the
raw files converted by hand: theta_r = |phi_o|, phi_r = 180 where phi_o > 0 (specular side),
0 where phi_o < 0 (source side) and at the normal; the 1.0e-4 fill values at grazing dropped.
"""

from collections import Counter

import numpy as np
import pytest
from conftest import REAL

from brdfjax.data.formats import _format_reader, load, starlink
from brdfjax.data.measurements import DataError

STARLINK = REAL / "starlink-v1p5-scatterworks"
CHASSIS = STARLINK / "chassis_brdf.csv"
SOLAR = STARLINK / "solar_array_brdf.csv"

# (file line, its text, theta_i, theta_r, phi_r, brdf), read off the files by hand.
CHASSIS_LINES = [
    (16, "75.00     -180.00     -89.00     0.00     1.56196e-04", 75.0, 89.0, 0.0, 1.56196e-04),
    (180, "75.00     -180.00     75.00     0.00     8.03803e+03", 75.0, 75.0, 180.0, 8.03803e+03),
    (286, "60.00     -180.00     0.00     0.00     1.38307e-02", 60.0, 0.0, 0.0, 1.38307e-02),
    (509, "41.40     -180.00     42.00     0.00     1.52696e+03", 41.4, 42.0, 180.0, 1.52696e+03),
    (643, "5.00     -180.00     -5.00     0.00     7.32859e-01", 5.0, 5.0, 0.0, 7.32859e-01),
    (736, "5.00     -180.00     88.00     0.00     1.89308e-02", 5.0, 88.0, 180.0, 1.89308e-02),
]
SOLAR_LINES = [
    (16, "75.00     -180.00     -89.00     0.00     9.33020e-04", 75.0, 89.0, 0.0, 9.33020e-04),
    (180, "75.00     -180.00     75.00     0.00     5.33414e+04", 75.0, 75.0, 180.0, 5.33414e+04),
    (286, "60.00     -180.00     0.00     0.00     2.88683e-03", 60.0, 0.0, 0.0, 2.88683e-03),
    (375, "60.00     -180.00     89.00     0.00     5.47554e-03", 60.0, 89.0, 180.0, 5.47554e-03),
    (508, "41.40     -180.00     41.00     0.00     1.29424e+01", 41.4, 41.0, 180.0, 1.29424e+01),
    (643, "5.00     -180.00     -5.00     0.00     1.10187e-01", 5.0, 5.0, 0.0, 1.10187e-01),
]
# Lines holding the fill value 1.0e-4 at |phi_o| >= 88, which must not load.
CHASSIS_FILLS = [(15, 75.0, 90.0, 0.0), (375, 60.0, 89.0, 180.0), (737, 5.0, 89.0, 180.0)]
SOLAR_FILLS = [(15, 75.0, 90.0, 0.0), (736, 5.0, 88.0, 180.0), (737, 5.0, 89.0, 180.0)]

# 181 readings per incidence, less the fill values.
COUNTS = {CHASSIS: {75.0: 179, 60.0: 177, 41.4: 176, 5.0: 177},
          SOLAR: {75.0: 180, 60.0: 179, 41.4: 176, 5.0: 176}}
FILLS = {CHASSIS: 15, SOLAR: 13}


def raw_rows(path):
    """(phi_i, theta_i, phi_o, theta_o, brdf) of every data line, by a plain text parse."""
    return [tuple(float(cell) for cell in line.split())
            for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]


def points_at(data, theta_i, theta_r, phi_r):
    """The brdf values of the points at one geometry (degrees)."""
    at = (np.isclose(np.degrees(data.theta_i), theta_i)
          & np.isclose(np.degrees(data.theta_r), theta_r)
          & np.isclose(np.degrees(data.phi_r), phi_r, atol=1e-9))
    return data.brdf[at]


@pytest.mark.parametrize(("path", "rows"), [(CHASSIS, CHASSIS_LINES), (SOLAR, SOLAR_LINES)])
def test_lines_converted_by_hand(path, rows):
    text = path.read_text().splitlines()
    data = load(path)
    for line, raw, theta_i, theta_r, phi_r, brdf in rows:
        assert text[line - 1] == raw
        assert points_at(data, theta_i, theta_r, phi_r).tolist() == [brdf], line


@pytest.mark.parametrize(("path", "fills"), [(CHASSIS, CHASSIS_FILLS), (SOLAR, SOLAR_FILLS)])
def test_fill_values_dropped(path, fills):
    text = path.read_text().splitlines()
    rows = raw_rows(path)
    fill_rows = [r for r in rows if r[4] == 1.0e-4 and abs(r[2]) >= 88]
    assert len(fill_rows) == FILLS[path]
    # No reading away from grazing holds the fill value: the rule loses no data.
    assert all(abs(r[2]) >= 88 for r in rows if r[4] == 1.0e-4)
    data = load(path)
    assert data.metadata["fill_values_dropped"] == FILLS[path]
    assert not np.any(data.brdf == 1.0e-4)
    assert len(data) == len(rows) - len(fill_rows)
    for line, theta_i, theta_r, phi_r in fills:
        assert float(text[line - 1].split()[4]) == 1.0e-4
        assert points_at(data, theta_i, theta_r, phi_r).size == 0, line


@pytest.mark.parametrize("path", [CHASSIS, SOLAR])
def test_point_counts_per_incidence(path):
    assert len(raw_rows(path)) == 724
    data = load(path)
    counts = Counter(np.round(np.degrees(data.theta_i), 6).tolist())
    assert counts == COUNTS[path]
    assert len(data) == sum(COUNTS[path].values()) == 724 - FILLS[path]


@pytest.mark.parametrize("path", [CHASSIS, SOLAR])
def test_in_plane_angles_and_metadata(path):
    data = load(path)
    assert _format_reader(path) is starlink
    assert data.in_plane
    phi = np.degrees(data.phi_r)
    assert set(np.round(phi, 9).tolist()) == {0.0, 180.0}
    assert np.all(phi[np.degrees(data.theta_r) == 0] == 0)
    # Both sides of the plane are there, one reading per whole degree of theta_r each.
    for side in (0.0, 180.0):
        assert np.sum(phi == side) > 300
    assert data.wavelength_nm == 532.0
    assert data.metadata["sample"] == path.stem
    assert "lambda = 532 nm" in data.metadata["header"]
    assert "Scatterworks" in data.metadata["header"]


@pytest.mark.parametrize("path", [CHASSIS, SOLAR])
def test_specular_peak_on_the_specular_side(path):
    data = load(path)
    theta_i = np.round(np.degrees(data.theta_i), 6)
    for incidence in COUNTS[path]:
        mine = theta_i == incidence
        peak = np.argmax(data.brdf[mine])
        assert np.degrees(data.phi_r[mine][peak]) == pytest.approx(180.0)
        # The grid is whole degrees, so the 41.4-deg peak reads at 41 or 42.
        assert abs(np.degrees(data.theta_r[mine][peak]) - incidence) < 1
        # The source-side mirror of the peak is orders of magnitude darker.
        mirror = points_at(data, incidence, round(incidence), 0.0)
        assert mirror.size == 1 and mirror[0] < 1e-2 * data.brdf[mine][peak]


def copy_with(tmp_path, name, change):
    """A copy of the chassis file under ``name``, its lines passed through ``change``."""
    lines = CHASSIS.read_text().splitlines()
    path = tmp_path / name
    path.write_text("\n".join(change(lines)) + "\n")
    return path


def test_bad_number_names_its_line(tmp_path):
    def corrupt(lines):
        assert lines[19] == "75.00     -180.00     -85.00     0.00     1.97328e-02"
        lines[19] = "75.00     -180.00     -85.00     0.00     1.9732Be-02"
        return lines

    path = copy_with(tmp_path, "bad.csv", corrupt)
    with pytest.raises(DataError, match=r"bad\.csv:20: brdf = '1\.9732Be-02' is not a number"):
        load(path)


def test_missing_cell_names_its_line(tmp_path):
    def corrupt(lines):
        lines[99] = lines[99].rsplit(maxsplit=1)[0]
        return lines

    with pytest.raises(DataError, match=r"short\.csv:100: 4 cells"):
        load(copy_with(tmp_path, "short.csv", corrupt))


def test_zenith_beyond_90_names_its_line(tmp_path):
    def corrupt(lines):
        lines[29] = lines[29].replace("-75.00", "-95.00")
        return lines

    with pytest.raises(DataError, match=r"beyond\.csv:30: theta_r = 95 deg"):
        load(copy_with(tmp_path, "beyond.csv", corrupt))


def test_detected_by_content_whatever_the_suffix(tmp_path):
    plain = copy_with(tmp_path, "chassis.txt", lambda lines: lines)
    # The column line as a plain (uncommented) header line, without the comments.
    bare = copy_with(tmp_path, "bare.dat",
                     lambda lines: ["phi_i theta_i phi_o theta_o brdf"] + lines[14:])
    for path in (plain, bare):
        assert _format_reader(path) is starlink
        assert len(load(path)) == 709
    assert "header" not in load(bare).metadata


def test_wavelength_from_the_header_else_532(tmp_path):
    stated = copy_with(tmp_path, "at633.csv",
                       lambda lines: [line.replace("lambda = 532 nm", "lambda = 633 nm")
                                      for line in lines])
    assert load(stated).wavelength_nm == 633.0
    with pytest.raises(DataError, match="no data at 532 nm"):
        load(stated, wavelength_nm=532)
    silent = copy_with(tmp_path, "silent.csv",
                       lambda lines: [line for line in lines if "lambda" not in line])
    assert load(silent).wavelength_nm == starlink.DEFAULT_WAVELENGTH_NM == 532.0
    assert load(silent, wavelength_nm=633).wavelength_nm == 633.0


def test_other_csvs_are_not_taken_for_starlink():
    assert not starlink.looks_like("theta_i,theta_r,phi_r,brdf\n10,0,0,0.2\n")
    assert not starlink.looks_like("lambda,thetai,phii,thetar,phir,fr11\n")
    # The column line must come before the data.
    assert not starlink.looks_like("75 -180 -90 0 1e-4\n# phi_i theta_i phi_o theta_o brdf\n")
    assert starlink.looks_like("# comment\n#\n# phi_i  theta_i  phi_o  theta_o  brdf\n1 2 3 4 5")
