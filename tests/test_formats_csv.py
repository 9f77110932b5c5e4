"""CSV files as spreadsheets save them, and geometry-only CSV files."""

from pathlib import Path

import numpy as np
import pytest

from brdfjax.data.formats import load, load_geometry
from brdfjax.data.measurements import DataError

REPO = Path(__file__).resolve().parents[1]
# The same three points, written by hand in each dialect.
EXPECTED = {"theta_i": [10, 10, 30], "theta_r": [0, 20.5, 40], "phi_r": [0, 180, 180],
            "brdf": [0.25, 0.125, 0.5]}
DIALECTS = {
    "comma": "theta_i,theta_r,phi_r,brdf\n10,0,0,0.25\n10,20.5,180,0.125\n30,40,180,0.5\n",
    "utf-8 BOM": "\ufefftheta_i,theta_r,phi_r,brdf\n10,0,0,0.25\n10,20.5,180,0.125\n"
                 "30,40,180,0.5\n",
    "semicolon": "theta_i;theta_r;phi_r;brdf\n10;0;0;0.25\n10;20.5;180;0.125\n30;40;180;0.5\n",
    "tab": "theta_i\ttheta_r\tphi_r\tbrdf\n10\t0\t0\t0.25\n10\t20.5\t180\t0.125\n30\t40\t180\t0.5\n",
    "decimal comma": "theta_i;theta_r;phi_r;brdf\n10;0;0;0,25\n10;20,5;180;0,125\n"
                     "30;40;180;0,5\n",
    "Excel UTF-8, quoted, CRLF": '\ufeff"Theta_i";"Theta_r";"Phi_r";"BRDF"\r\n'
                                 '10;0;0;"0,25"\r\n10;20,5;180;0,125\r\n30;40;180;0,5\r\n',
}


@pytest.mark.parametrize("text", DIALECTS.values(), ids=list(DIALECTS))
def test_every_dialect_gives_the_same_points(tmp_path, text):
    path = tmp_path / "d.csv"
    path.write_bytes(text.encode("utf-8"))
    data = load(path)
    for name in ("theta_i", "theta_r", "phi_r"):
        np.testing.assert_allclose(np.degrees(getattr(data, name)), EXPECTED[name])
    np.testing.assert_allclose(data.brdf, EXPECTED["brdf"])


def test_latin1_comment_does_not_stop_the_file(tmp_path):
    path = tmp_path / "latin.csv"
    path.write_bytes("# sample: peinture blanche \xe9mail\ntheta_i,theta_r,phi_r,brdf\n"
                     "10,0,0,0.25\n".encode("latin-1"))
    data = load(path)
    assert data.metadata["sample"] == "peinture blanche \xe9mail"


def test_decimal_comma_with_comma_separators_is_refused_with_the_reason(tmp_path):
    path = tmp_path / "ambiguous.csv"
    path.write_text("theta_i,theta_r,phi_r,brdf\n10,0,0,0,25\n")
    with pytest.raises(DataError, match=r"ambiguous.csv:2: 5 cells, the header has 4 .*"
                                        r"decimal point .*decimal commas needs ';'"):
        load(path)


def test_geometry_only_csv(tmp_path):
    path = tmp_path / "geometry.csv"
    path.write_text("theta_i,theta_r,phi_r\n10,0,0\n10,20.5,180\n30,40,180\n")
    data = load_geometry(path)
    assert len(data) == 3 and not data.has_brdf and np.all(np.isnan(data.brdf))
    np.testing.assert_allclose(np.degrees(data.theta_r), EXPECTED["theta_r"])
    # Where values are needed the message says brdf is missing, and lists nothing present.
    with pytest.raises(DataError) as error:
        load(path)
    message = str(error.value)
    assert "geometry.csv:1: no brdf column" in message
    assert "theta_i" not in message and "phi_r" not in message


def test_geometry_only_angles_are_still_checked(tmp_path):
    path = tmp_path / "geometry.csv"
    path.write_text("theta_i;theta_r;phi_r\n10;0;0\n10;95;180\n")
    with pytest.raises(DataError, match=r"geometry.csv:3: theta_r = 95 deg is outside"):
        load_geometry(path)
    path.write_text("theta_i;theta_r;phi_r\n10;0;0\n30;10;-400\n")
    with pytest.raises(DataError, match=r"geometry.csv:3: phi_r = -400 deg is beyond one turn"):
        load_geometry(path)


def test_a_geometry_file_without_an_angle_names_what_it_needs(tmp_path):
    """A geometry file needs the three angles; brdf is optional there, and the hint says so
    (it listed brdf as required)."""
    path = tmp_path / "geometry.csv"
    path.write_text("incidence,theta_r,phi_r\n10,0,0\n")
    with pytest.raises(DataError) as error:
        load_geometry(path)
    assert str(error.value) == (f"{path}:1: missing column theta_i (the header must name "
                                "theta_i,theta_r,phi_r (optional: brdf, sigma, weight))")
    with pytest.raises(DataError, match=r"must name theta_i,theta_r,phi_r,brdf \(optional: "
                                        r"sigma, weight\)"):
        load(path)


def test_load_geometry_of_a_file_with_values_keeps_them(white_paint):
    data = load_geometry(REPO / "data" / "synthetic" / "white_paint.csv")
    assert data.has_brdf
    np.testing.assert_array_equal(data.brdf, white_paint.brdf)


def test_wavelength_option_is_checked_against_the_file(tmp_path):
    path = tmp_path / "w.csv"
    path.write_text("# wavelength_nm: 633\ntheta_i,theta_r,phi_r,brdf\n10,0,0,0.25\n")
    assert load(path, wavelength_nm=633.2).metadata["wavelength_nm"] == "633"
    with pytest.raises(DataError, match="no data at 532 nm; the file holds 633 nm"):
        load(path, wavelength_nm=532)


def test_a_column_named_twice_is_refused(tmp_path):
    path = tmp_path / "twice.csv"
    path.write_text("theta_i,theta_r,phi_r,brdf,brdf\n10,0,0,0.25,0.3\n")
    with pytest.raises(DataError, match="twice.csv:1: column brdf named twice"):
        load(path)
