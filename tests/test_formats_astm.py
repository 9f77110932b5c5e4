"""ASTM E1392: hand-written files, conventions, spectral columns, round trips, model export."""


import numpy as np
import pytest
from conftest import REAL

from brdfjax.data.formats import astm, load, load_spectral, save, zemax
from brdfjax.data.measurements import DataError

AUTHORS_BSDF = REAL / "uaz-loft-rt300s" / "processed_by_authors"
PI = np.pi


def write(path, vars_line, rows, header="SOURCE hand-written test\n"):
    lines = [",".join(f"{x!r}" if isinstance(x, float) else str(x) for x in row)
             for row in rows]
    path.write_text(header + f"NUM_POINTS {len(rows)}\nVARS {vars_line}\n"
                    + "\n".join(lines) + "\n")
    return path


def test_angles_are_radians_and_phi_i_is_rotated_away(tmp_path):
    # Source at phi_i = 90 deg. Detector at phi_s = 270 deg is the specular side (180),
    # phi_s = 90 deg the source side (0), phi_s = 0 deg is phi_r = -90, phi_s = 135 is 45.
    rows = [(PI / 6, PI / 2, PI / 6, 3 * PI / 2, 0.5),
            (PI / 6, PI / 2, PI / 4, PI / 2, 0.25),
            (PI / 6, PI / 2, PI / 3, 0.0, 0.125),
            (PI / 6, PI / 2, PI / 3, 3 * PI / 4, 0.375),
            (PI / 6, PI / 2, 0.0, 1.0, 0.0625)]
    data = load(write(tmp_path / "r.astm", "theta_i,phi_i,theta_s,phi_s,BRDF", rows))
    np.testing.assert_allclose(np.degrees(data.theta_i), 30)
    np.testing.assert_allclose(np.degrees(data.theta_r), [30, 45, 60, 60, 0])
    np.testing.assert_allclose(np.degrees(data.phi_r), [180, 0, -90, 45, 0], atol=1e-9)
    np.testing.assert_array_equal(np.degrees(data.phi_r)[:2], [180, 0])  # exactly in-plane
    np.testing.assert_allclose(data.brdf, [0.5, 0.25, 0.125, 0.375, 0.0625])
    assert data.metadata["source"] == "hand-written test"
    assert data.metadata["format"] == "ASTM E1392"


def test_negative_polar_angle_is_the_opposite_azimuth(tmp_path):
    rows = [(-PI / 6, 0.0, PI / 6, 0.0, 0.5), (PI / 6, 0.0, -PI / 6, 0.0, 0.25)]
    data = load(write(tmp_path / "n.astm", "theta_i,phi_i,theta_s,phi_s,BRDF", rows))
    # (-30, 0) is (30, 180): the first detector then lies at phi_r = -180 = 180.
    np.testing.assert_allclose(np.degrees(data.phi_r), [180, 180])


def test_columns_in_another_order(tmp_path):
    rows = [(0.3, PI, 0.2, 0.0, 0.0), (0.4, PI, 0.2, 0.0, 0.0)]
    data = load(write(tmp_path / "o.astm", "BRDF,phi_s,theta_s,phi_i,theta_i",
                      [(0.3, PI, 0.2, 0.0, 0.1), (0.4, PI, 0.2, 0.0, 0.1)]))
    np.testing.assert_allclose(data.brdf, [r[0] for r in rows])
    np.testing.assert_allclose(data.theta_i, 0.1)
    np.testing.assert_allclose(np.degrees(data.phi_r), 180)


SPECTRAL_ROWS = [(PI / 6, 0.0, PI / 6, PI, 0.5, 0.6), (PI / 6, 0.0, 0.2, PI, 0.25, 0.3)]


def test_spectral_columns(tmp_path):
    path = write(tmp_path / "s.astm", "theta_i,phi_i,theta_s,phi_s,550nm,650.5nm",
                 SPECTRAL_ROWS)
    with pytest.raises(DataError, match="2 wavelengths: 550, 650.5 nm"):
        load(path)
    np.testing.assert_allclose(load(path, wavelength_nm=650.5).brdf, [0.6, 0.3])
    every = load_spectral(path)
    assert list(every) == [550.0, 650.5]
    np.testing.assert_allclose(every[550.0].brdf, [0.5, 0.25])
    assert every[650.5].metadata["wavelength_nm"] == 650.5
    assert list(load_spectral(path, [650])) == [650.5]
    with pytest.raises(DataError, match="no data at 700 nm; the file holds 550, 650.5 nm"):
        load_spectral(path, [550, 700])


def test_spectral_nist_file_has_four_wavelengths():
    every = load_spectral(REAL / "nist-germer-ptfe" / "PTFE.data.csv")
    assert list(every) == [351.0, 532.0, 633.0, 1064.0]
    assert all(len(d) == 1824 for d in every.values())
    assert every[633.0].metadata["wavelength_nm"] == 633.0


def test_rgb_outputs_are_refused(tmp_path):
    path = write(tmp_path / "rgb.astm", "theta_i,phi_i,theta_s,phi_s,R,G,B",
                 [(0.1, 0.0, 0.2, PI, 0.1, 0.2, 0.3)])
    with pytest.raises(DataError, match=r"rgb.astm:3: outputs R, G, B are neither one BRDF"):
        load(path)


@pytest.mark.parametrize("header,message", [
    ("NUM_POINTS 3\n", r"c.astm:1: NUM_POINTS is '3', but 2 data lines follow"),
    ("NUM_POINTS two\n", r"c.astm:1: NUM_POINTS is 'two'"),
])
def test_wrong_point_count(tmp_path, header, message):
    path = tmp_path / "c.astm"
    path.write_text(header + "VARS theta_i,phi_i,theta_s,phi_s,BRDF\n0.1,0,0.2,3.1,0.5\n"
                    "0.1,0,0.3,3.1,0.5\n")
    with pytest.raises(DataError, match=message):
        load(path)


def test_detected_by_content(tmp_path):
    path = write(tmp_path / "scan.txt", "theta_i,phi_i,theta_s,phi_s,BRDF",
                 [(0.1, 0.0, 0.2, PI, 0.5)])
    assert len(load(path)) == 1


def test_round_trip_with_brdfjax_csv(tmp_path, white_paint):
    save(white_paint, tmp_path / "w.astm")
    text = (tmp_path / "w.astm").read_text()
    assert "VARS theta_i,phi_i,theta_s,phi_s,1060nm" in text and "NUM_POINTS 1074" in text
    back = load(tmp_path / "w.astm")
    save(back, tmp_path / "w.csv")
    again = load(tmp_path / "w.csv")
    for data in (back, again):
        np.testing.assert_allclose(data.theta_i, white_paint.theta_i, atol=1e-11)
        np.testing.assert_allclose(data.theta_r, white_paint.theta_r, atol=1e-11)
        np.testing.assert_array_equal(np.cos(data.phi_r), np.cos(white_paint.phi_r))
        np.testing.assert_allclose(data.brdf, white_paint.brdf, rtol=1e-11)
    assert again.metadata["sample"] == "white_paint"
    assert float(again.metadata["wavelength_nm"]) == 1060


def test_round_trip_with_the_authors_zemax_table(tmp_path):
    # The padding zeros kept, so the points fill the table's grid again.
    table = zemax.read(AUTHORS_BSDF / "AnoBlackNiTEonSteel.bsdf", wavelength_nm=650,
                       keep_zeros=True)
    save(table, tmp_path / "n.astm")
    back = load(tmp_path / "n.astm")
    assert len(back) == len(table) == 647 + 59
    np.testing.assert_allclose(back.brdf, table.brdf, rtol=1e-11)
    np.testing.assert_allclose(back.theta_r, table.theta_r, atol=1e-11)
    assert back.metadata["sample"] == table.metadata["sample"]
    # And back into a Zemax table: the same cells.
    save(back, tmp_path / "n.bsdf")
    again = zemax.read(tmp_path / "n.bsdf", keep_zeros=True)
    np.testing.assert_allclose(again.brdf, table.brdf, rtol=1e-6)
    np.testing.assert_allclose(again.theta_r, table.theta_r, atol=1e-9)


def test_model_export_matches_the_model_and_the_zemax_export(tmp_path):
    from brdfjax.models.paper import PAPER_SAMPLES, brdf

    params = PAPER_SAMPLES["white_paint"]
    astm.write_model_astm(tmp_path / "m.astm", params, [0, 30, 60], np.arange(0, 90, 10),
                          [0, 90, 180], sample="white paint", wavelength_nm=1060)
    data = load(tmp_path / "m.astm")
    # 3 incidences x (1 normal + 8 zenith angles x 3 azimuths).
    assert len(data) == 3 * 25 and data.metadata["sample"] == "white paint"
    assert data.metadata["wavelength_nm"] == 1060
    assert "kb=5.708" in (tmp_path / "m.astm").read_text()
    expected = np.asarray(brdf(params, data.theta_i, data.theta_r, data.phi_r))
    np.testing.assert_allclose(data.brdf, expected, rtol=1e-11)
    # The Zemax export of the same model agrees where their grids meet (the plane).
    zemax.write_model(tmp_path / "m.bsdf", params, [30], [0, 180], np.arange(0, 91, 10))
    table = zemax.read(tmp_path / "m.bsdf")
    ours = data.at_incidences([30])
    for theta, phi, value in zip(table.theta_r, np.cos(table.phi_r), table.brdf):
        match = (np.abs(ours.theta_r - theta) < 1e-9) & (np.cos(ours.phi_r) == phi)
        if match.any():
            assert ours.brdf[match][0] == pytest.approx(value, rel=5.1e-7)


def test_angles_in_degrees_are_refused(tmp_path):
    path = write(tmp_path / "deg.astm", "theta_i,phi_i,theta_s,phi_s,BRDF",
                 [(0.5, 0.0, 0.2, 3.0, 0.1), (30, 0, 20, 180, 0.1)])
    with pytest.raises(DataError, match=r"deg.astm:5: theta_i = 30 is not a polar angle in "
                                        r"radians .*written in degrees"):
        load(path)


def test_info_on_a_file_of_several_wavelengths_summarises_each(capsys):
    """``brdfjax info`` without --wavelength lists every wavelength with its points and
    BRDF range (it was an error), each checked against the file's own columns."""
    import csv

    from brdfjax.cli import main

    path = REAL / "nist-germer-ptfe" / "PTFE.data.csv"
    by_wavelength = {}
    with open(path, encoding="utf-8") as handle:
        for row in csv.DictReader(handle):
            by_wavelength.setdefault(round(float(row["lambda"]) * 1000), []).append(
                float(row["f_r11"]))
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "wavelengths: 4: 351, 532, 633, 1064 nm" in out
    for nm, values in by_wavelength.items():
        line = next(line for line in out.splitlines() if line.split()[:1] == [f"{nm}"])
        assert line.split()[1] == str(len(values))
        assert line.endswith(f"{min(values):.4g} to {max(values):.4g}")
