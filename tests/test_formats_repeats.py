"""Repeated geometry is data: every reading kept, summarised by ``info``; incidence bins."""


import numpy as np
import pytest
from conftest import REAL

from brdfjax.cli import main
from brdfjax.data.formats import load, nist, save, zemax
from brdfjax.data.measurements import Measurements, repeat_summary

PTFE_RANDOM = REAL / "nist-germer-ptfe" / "PTFE.data.random.csv"


def grid_csv(path, incidences=(5, 30)):
    """A standard out-of-plane grid: theta_r 0 to 85 in 5, phi_r 0/45/90/135/180."""
    rows = ["theta_i,theta_r,phi_r,brdf"]
    for ti in incidences:
        for tr in range(0, 90, 5):
            for pr in (0, 45, 90, 135, 180):
                rows.append(f"{ti},{tr},{pr},{0.1 + 0.001 * tr + 0.0001 * pr}")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_pole_at_every_azimuth_loads_every_reading(tmp_path):
    data = load(grid_csv(tmp_path / "grid.csv"))
    assert len(data) == 2 * 18 * 5
    pole = data.theta_r == 0
    assert pole.sum() == 10  # 5 azimuths x 2 incidences, none dropped or merged
    np.testing.assert_allclose(np.sort(data.brdf[pole][:5]), 0.1 + 0.0001 * np.array(
        [0, 45, 90, 135, 180]))
    summary = repeat_summary(data)
    assert (summary.geometries, summary.readings, summary.most) == (2, 10, 5)


def test_repeated_readings_are_kept_and_their_spread_reported(tmp_path, capsys):
    path = tmp_path / "repeats.csv"
    path.write_text("theta_i,theta_r,phi_r,brdf\n10,20,180,0.1\n10,20,180,0.2\n"
                    "10,20,-180,0.3\n10,40,180,0.5\n")
    data = load(path)
    np.testing.assert_allclose(data.brdf, [0.1, 0.2, 0.3, 0.5])
    groups = data.repeat_groups()
    assert groups[0] == groups[1] == groups[2] != groups[3]  # phi_r -180 is 180
    # Readings 0.1, 0.2, 0.3: std (ddof 1) 0.1 over mean 0.2 = 50 %.
    assert repeat_summary(data).median_spread == pytest.approx(0.5)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "repeats:     1 geometries read more than once (3 readings, up to 3" in out
    assert "median 50 %, max 50 %" in out


ZEMAX_HEADER = """Source\tMeasured
Symmetry\tPlaneSymmetrical
SpectralContent\tMonochrome
ScatterType\tBRDF
SampleRotation\t1
0
AngleOfIncidence\t1
20
ScatterAzimuth\t3
0\t90\t180
ScatterRadial\t3
0\t10\t20
Monochrome
DataBegin
TIS\t0.1
"""


@pytest.mark.parametrize("specular,kept", [((0.5, 0.5, 0.5), 1), ((0.4, 0.5, 0.6), 3)])
def test_zemax_specular_copies_are_one_reading_different_values_are_three(
        tmp_path, specular, kept):
    rows = "".join(f"{s}\t0.2\t0.3\n" for s in specular)
    path = tmp_path / "t.bsdf"
    path.write_text(ZEMAX_HEADER + rows + "DataEnd\n")
    data = zemax.read(path)
    at_specular = (np.abs(np.degrees(data.theta_r) - 20) < 1e-9) & (np.cos(data.phi_r) < 0)
    assert at_specular.sum() == kept
    np.testing.assert_allclose(np.sort(data.brdf[at_specular]), sorted(set(specular)))
    assert len(data) == kept + 6
    # The same points written as CSV load as the same readings.
    save(data, tmp_path / "t.csv")
    again = load(tmp_path / "t.csv")
    np.testing.assert_allclose(again.brdf, data.brdf, rtol=1e-9)


def test_zemax_write_averages_repeats_into_their_cell(tmp_path):
    path = tmp_path / "t.bsdf"
    path.write_text(ZEMAX_HEADER + "0.4\t0.2\t0.3\n0.5\t0.2\t0.3\n0.6\t0.2\t0.3\nDataEnd\n")
    data = zemax.read(path)
    save(data, tmp_path / "back.bsdf")
    back = zemax.read(tmp_path / "back.bsdf")
    assert len(back) == 7
    specular = np.argmin(np.abs(np.degrees(back.theta_r) - 20) + np.cos(back.phi_r) + 1)
    assert back.brdf[specular] == pytest.approx(0.5)  # (0.4 + 0.5 + 0.6) / 3
    assert "2 repeated readings averaged" in (tmp_path / "back.bsdf").read_text()


def test_nist_repeated_rows_are_kept(tmp_path):
    path = tmp_path / "ptfe.csv"
    path.write_text("lambda,thetai,phii,thetar,phir,fr11\n0.532,-30,0,20,0,0.30\n"
                    "0.532,-30,0,20,0,0.32\n0.532,-30,0,40,0,0.31\n")
    data = nist.read(path)
    np.testing.assert_allclose(data.brdf, [0.30, 0.32, 0.31])


def test_incidence_bins_of_distinct_incidences(white_paint):
    bins = white_paint.incidence_bins()
    assert bins.labels == ("10 deg", "21 deg", "30 deg", "45 deg", "52 deg", "60 deg")
    incidence = np.array([10, 21, 30, 45, 52, 60])[bins.index]
    np.testing.assert_allclose(np.degrees(white_paint.theta_i), incidence)


def test_incidence_bins_of_the_random_ptfe_file():
    data = load(PTFE_RANDOM)
    assert len(data) == 1760 and len(data.incidences_deg) > 1700
    bins = data.incidence_bins(max_bins=8)
    counts = np.bincount(bins.index)
    assert len(bins.labels) == len(counts) == 8
    # Equal-count bins: 220 points each if the quantiles fell on whole degrees.
    assert counts.min() > 150 and counts.max() < 300 and counts.sum() == 1760
    theta = np.degrees(data.theta_i)
    for k, label in enumerate(bins.labels):
        low, high = (float(x) for x in label.removesuffix(" deg").split("-"))
        assert low == round(low) and high == round(high)
        inside = theta[bins.index == k]
        assert inside.min() >= low and inside.max() <= high
    assert bins.labels[0].startswith("1-") and bins.labels[-1].endswith("-74 deg")
    assert list(bins.label_of_points()[:1]) == [bins.labels[bins.index[0]]]


def test_info_summarises_scattered_incidences_as_bins(capsys):
    assert main(["info", str(PTFE_RANDOM)]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines()
                if x.startswith("incidences:"))
    assert len(line) < 250
    assert "1756 distinct, 1.01752 to 73.8757 deg; bins (points): 1-20 (229)" in line


def test_incidence_bins_need_one_bin():
    data = Measurements([0.1], [0.2], [0.0], [1.0])
    with pytest.raises(ValueError, match="max_bins must be at least 1"):
        data.incidence_bins(max_bins=0)
