"""The command line: help everywhere, outputs people read, files people keep."""

import json

import numpy as np
import pytest
from conftest import DATA

from brdfjax.cli import build_parser, main
from brdfjax.model import PAPER_SAMPLES, brdf


def commands(parser):
    """Every (sub)command path of the CLI, e.g. ["fit"], ["instrument", "simulate"]."""
    found = []
    for action in parser._subparsers._group_actions if parser._subparsers else []:
        for name, sub in action.choices.items():
            found.append([name])
            found += [[name, *rest] for rest in commands(sub)]
    return found


@pytest.mark.parametrize("path", commands(build_parser()), ids=" ".join)
def test_every_command_has_help(path, capsys):
    with pytest.raises(SystemExit) as stop:
        main([*path, "--help"])
    assert stop.value.code == 0
    assert "usage: brdfjax " + " ".join(path) in capsys.readouterr().out


def test_eval_prints_the_model(capsys):
    assert main(["eval", "--params", "white_paint", "--theta-i", "30", "--theta-r", "0:80:40",
                 "--phi-r", "0,180"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == "theta_i,theta_r,phi_r,brdf,projected"
    rows = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    assert rows.shape == (6, 5)
    expected = brdf(PAPER_SAMPLES["white_paint"], *np.radians(rows[:, :3].T))
    np.testing.assert_allclose(rows[:, 3], expected, rtol=1e-9)


def test_reflectance_flags_energy_creation(capsys):
    assert main(["reflectance", "--params", "polyimide", "--theta-i", "0"]) == 0
    out = capsys.readouterr().out
    assert "0,7.6087" in out and "warning: reflectance up to 7.6" in out
    with pytest.raises(SystemExit) as stop:  # argparse: five numbers needed
        main(["reflectance", "--params", "1,2"])
    assert stop.value.code == 2
    assert "give five numbers" in capsys.readouterr().err


def test_fit_writes_json_and_plots(tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--validate-incidence", "21,52",
                 "--json", str(out), "--plot", str(tmp_path / "fit.png"),
                 "--plot-3d", str(tmp_path / "3d.png"), "--incidences-3d", "30"]) == 0
    table = capsys.readouterr().out
    assert "status converged" in table and "held out: E =" in table
    result = json.loads(out.read_text())
    assert set(result["params"]) == {"kb", "kr", "a", "b", "kd"}
    assert 0 < result["error"] < 0.01  # a fraction, not a percent
    assert set(result["error_by_incidence"]) == {"10", "30", "45", "60"}
    assert set(result["validation_by_incidence"]) == {"21", "52"}
    assert result["status"] == "converged" and set(result["timings"]) >= {"total"}
    for name in ("fit.png", "3d.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"


def test_train_incidence_holds_out_the_rest(tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--train-incidence", "10,30,45,60",
                 "--json", str(out)]) == 0
    assert set(json.loads(out.read_text())["validation_by_incidence"]) == {"21", "52"}


def test_convert_and_info(tmp_path, capsys):
    target = tmp_path / "steel.csv"
    source = str(DATA / "real/uaz-loft-rt300s/raw/NiTE_on_steel_v1o0A_20250915.xls")
    assert main(["convert", source, str(target)]) == 0
    assert main(["info", str(target)]) == 0
    out = capsys.readouterr().out
    assert "incidences:  10, 30, 50, 70 deg" in out and "in-plane:    yes" in out


def test_demo_reproduces_the_papers_white_paint(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "white_paint      0.7341" in out  # Eq. (9) with the paper's parameters: 73.4 %
    assert "polyimide" in out and "not energy-conserving" in out
    assert "E (held out)" in out and "status converged" in out
    assert (tmp_path / "demo_fit.png").exists() and (tmp_path / "demo_hemisphere.png").exists()


def test_fit_summary_flags_a_fit_that_creates_energy(capsys):
    assert main(["fit", str(DATA / "synthetic" / "polyimide.csv"), "--uncertainty", "none"]) == 0
    out = capsys.readouterr().out
    assert "reflectance rho(0, 30, 60 deg) = 7.6" in out
    assert "warning: reflectance up to 7.6" in out and "not physical" in out
