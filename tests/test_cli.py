"""The command line: help everywhere, outputs people read, files people keep."""

import json
import re
import warnings

import numpy as np
import pytest
import transcription
from conftest import DATA, REAL

from brdfjax.cli import build_parser, main
from brdfjax.models.paper import PAPER_SAMPLES, brdf


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


def numbers(pattern, text):
    """The groups of the first line of ``text`` that matches ``pattern``, as floats."""
    return np.array(re.search(pattern, text, re.MULTILINE).groups(), dtype=float)


def independent_rho(params, degrees):
    """Eq. (9) by the tests' own integrator of the transcription (tests/transcription.py)."""
    return np.array([transcription.reflectance("five", tuple(map(float, params)), np.radians(d))
                     for d in degrees])


def test_reflectance_flags_energy_creation(capsys):
    assert main(["reflectance", "--params", "polyimide", "--theta-i", "0"]) == 0
    out, err = capsys.readouterr()
    (printed,) = numbers(r"^0,([0-9.]+)$", out)
    expected = independent_rho(PAPER_SAMPLES["polyimide"], [0.0])[0]  # 7.60873...
    assert printed == pytest.approx(expected, rel=1e-6, abs=5e-7)  # %.6f
    assert f"warning: reflectance up to {expected:.3f} > 1" in out
    assert err == ""  # said once, not again as Python's EnergyWarning
    # the model's parameter count is checked once the model is known: a user error, exit 1
    assert main(["reflectance", "--params", "1,2"]) == 1
    assert "give 5 numbers kb,kr,a,b,kd for the five model" in capsys.readouterr().err
    assert main(["reflectance", "--params", "1,2", "--model", "ggx"]) == 1
    assert "give 4 numbers ks,alpha,f0,kd for the ggx model" in capsys.readouterr().err


def test_fit_writes_json_and_plots(tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--validate-incidence", "21,52",
                 "--json", str(out), "--plot", str(tmp_path / "fit.png"),
                 "--plot-3d", str(tmp_path / "3d.png"), "--incidences-3d", "30"]) == 0
    table = capsys.readouterr().out
    assert "status converged" in table and "held out: E =" in table
    assert f"wrote {out}, {tmp_path / 'fit.png'}, {tmp_path / '3d.png'}" in table
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
    source = str(REAL / "uaz-loft-rt300s/raw/NiTE_on_steel_v1o0A_20250915.xls")
    assert main(["convert", source, str(target), "--in-plane"]) == 0
    assert main(["info", str(target)]) == 0
    out = capsys.readouterr().out
    assert "incidences:  10, 30, 50, 70 deg" in out and "in-plane:    yes" in out


def test_demo_reproduces_the_papers_white_paint(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    # Eq. (9) with the paper's parameters (white paint 0.7341 at 0 deg: the paper's 73.4 %),
    # every printed digit against the independent integration of the transcription.
    for name, params in PAPER_SAMPLES.items():
        printed = numbers(rf"^  {name} +([0-9.]+) +([0-9.]+) +([0-9.]+)", out)
        np.testing.assert_allclose(printed, independent_rho(params, [0.0, 30.0, 60.0]), rtol=1e-6,
                                   atol=5e-5)  # %.4f, and the quadrature's 1e-6
    assert "polyimide" in out and "not energy-conserving" in out
    assert "E (held out)" in out and "status converged" in out
    assert "XLA compilations" in out or "compiled code loaded from the cache" in out
    assert (tmp_path / "demo_fit.png").exists() and (tmp_path / "demo_hemisphere.png").exists()


def test_fit_summary_flags_a_fit_that_creates_energy(capsys):
    assert main(["fit", str(DATA / "synthetic" / "polyimide.csv"), "--uncertainty", "none"]) == 0
    out, err = capsys.readouterr()
    assert "EnergyWarning" not in err  # said once, in the summary
    # The printed rho of the printed (6-digit) parameters, against the independent integral.
    params = [numbers(rf"^ +{k} = +(\S+)", out)[0] for k in ("kb", "kr", "a", "b", "kd")]
    rho = numbers(r"reflectance rho\(0, 30, 60 deg\) = (\S+), (\S+), (\S+)$", out)
    np.testing.assert_allclose(rho, independent_rho(params, [0.0, 30.0, 60.0]), rtol=2e-5)
    assert f"warning: reflectance up to {rho.max():.3f} > 1" in out and "not physical" in out


def test_the_help_names_every_model():
    from brdfjax.commands import OTHER_MODELS
    from brdfjax.models import available

    named = {name.strip() for name in OTHER_MODELS.split(", or ")[0].split(",")}
    assert named | {"five"} == set(available())


def test_every_argument_has_help():
    import argparse

    def missing(parser, path):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    yield from missing(sub, [*path, name])
            elif action.help is None:
                yield " ".join(path) + " " + (action.option_strings or [action.dest])[0]

    assert list(missing(build_parser(), ["brdfjax"])) == []


def test_an_extreme_value_is_refused_before_the_fit_with_no_raw_warning(tmp_path, capsys):
    lines = (DATA / "synthetic" / "white_paint.csv").read_text().splitlines()
    first = next(k for k, line in enumerate(lines) if line[:1].isdigit())
    cells = lines[first].split(",")
    lines[first] = ",".join([*cells[:3], "1e308", *cells[4:]])
    path = tmp_path / "huge.csv"
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "fit.json"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning that escaped main would raise here
        code = main(["fit", str(path), "--uncertainty", "none", "--json", str(out)])
    assert code == 1
    captured = capsys.readouterr()
    assert captured.out == "" and not out.exists()
    assert captured.err.startswith(f"brdfjax fit: error: {path}:{first + 1}: ")
    assert "Warning" not in captured.err


@pytest.mark.parametrize("model", ["five", "auto"])
def test_a_bad_predict_geometry_is_refused_before_any_fit(tmp_path, capsys, model):
    """--predict's file is read and checked with the inputs, before any fitting: nothing is
    printed (no model choice, no fit summary) and the error names the option, the file and
    its line (two files are read: the option says which one failed)."""
    geometry = tmp_path / "geometry.csv"
    geometry.write_text("theta_i,theta_r,phi_r\n10,20,0\n10,95,180\n")
    code = main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--model", model,
                 "--uncertainty", "none", "--predict", str(geometry),
                 "--predict-out", str(tmp_path / "pred.csv")])
    assert code == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith(f"brdfjax fit: error: --predict {geometry}:3: ")
    assert not (tmp_path / "pred.csv").exists()
    missing = tmp_path / "nosuch.csv"
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--model", model,
                 "--predict", str(missing), "--predict-out", str(tmp_path / "pred.csv")]) == 1
    assert capsys.readouterr().err.startswith(
        f"brdfjax fit: error: --predict {missing}: no such file")


def test_mcmc_without_emcee_is_one_clear_error_before_the_fit(tmp_path, capsys, monkeypatch):
    import sys

    import brdfjax.fitting.fit

    monkeypatch.setitem(sys.modules, "emcee", None)  # its import now fails

    def fit(*args, **kwargs):
        raise AssertionError("fitted before emcee was checked")

    monkeypatch.setattr(brdfjax.fitting.fit, "fit", fit)
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"),
                 "--uncertainty", "mcmc"]) == 1
    assert capsys.readouterr().err.strip().splitlines() == [
        ("brdfjax fit: error: MCMC sampling (--uncertainty mcmc) needs emcee, which is not "
        "installed here: pip install 'brdfjax[mcmc]' (in a checkout of brdfjax: pip install "
        "-e '.[mcmc]')")]


@pytest.mark.parametrize("module, argv, said", [
    ("corner", ["fit", str(DATA / "synthetic" / "white_paint.csv"), "--plot-corner", "c.png"],
     ("the corner plot (--plot-corner) needs corner, which is not installed here: "
      "pip install 'brdfjax[mcmc]' (in a checkout of brdfjax: pip install -e '.[mcmc]')")),
    ("serial", ["measure", "--port", "/dev/null", "--incidence", "10", "--out", "m.csv"],
     ("the instrument driver (brdfjax measure) needs pyserial, which is not installed here: "
      "pip install 'brdfjax[instrument]' (in a checkout of brdfjax: pip install -e "
      "'.[instrument]')")),
])
def test_a_missing_optional_package_is_one_line_before_any_work(module, argv, said, tmp_path,
                                                               capsys, monkeypatch):
    import sys

    import brdfjax.fitting.fit

    monkeypatch.setitem(sys.modules, module, None)  # its import now fails
    monkeypatch.setattr(brdfjax.fitting.fit, "fit", None)  # a fit would fail otherwise
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 1
    assert capsys.readouterr().err == f"brdfjax {argv[0]}: error: {said}\n"
    assert list(tmp_path.iterdir()) == []


def test_a_bad_setting_is_named_before_a_missing_pyserial(tmp_path, capsys, monkeypatch):
    """``measure`` checks its settings before it asks for pyserial: without pyserial, a
    target width of 0 was answered with the pyserial error (found by a newcomer)."""
    import sys

    monkeypatch.setitem(sys.modules, "serial", None)  # its import now fails
    monkeypatch.chdir(tmp_path)
    base = ["measure", "--port", "/dev/null", "--incidence", "10,30,50", "--out", "m.csv"]
    assert main([*base, "--adaptive", "--target-width", "0"]) == 1
    assert "--target-width 0 %: give the median 95 % half-width" in capsys.readouterr().err
    assert main([*base, "--target-width", "5"]) == 1
    assert "--target-width: only with --adaptive" in capsys.readouterr().err
    assert main([*base, "--adaptive"]) == 1  # good settings: then pyserial is asked for
    assert "needs pyserial, which is not installed here" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_an_import_error_that_is_a_bug_keeps_its_traceback(monkeypatch):
    """Only a missing optional package (MissingDependency) is a one-line user error."""
    import brdfjax.commands.data as command

    def broken(args):
        from brdfjax.fitting.fit import no_such_name  # noqa: F401

    monkeypatch.setattr(command, "run_info", broken)
    with pytest.raises(ImportError, match="no_such_name"):
        main(["info", str(DATA / "synthetic" / "white_paint.csv")])


def test_a_failed_fit_exits_1_with_the_reason(tmp_path, capsys, monkeypatch):
    """A fit whose status is failed (no finite E anywhere) exits 1; its JSON says why. (The
    fit made failed is that of the other white-paint tests, 21 and 52 deg held out, so its
    compiled stages come from their on-disk cache where one of them ran first.)"""
    import dataclasses

    import brdfjax.fitting.fit

    real = brdfjax.fitting.fit.fit

    def failing(*args, **kwargs):
        return dataclasses.replace(real(*args, **kwargs), status="failed", error=float("nan"))

    monkeypatch.setattr(brdfjax.fitting.fit, "fit", failing)
    out = tmp_path / "fit.json"
    code = main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--uncertainty", "none",
                 "--validate-incidence", "21,52", "--json", str(out)])
    assert code == 1
    captured = capsys.readouterr()
    assert "status failed" in captured.out and "the fit failed" in captured.err
    assert f"(the result, status failed, is in {out})" in captured.err
    record = json.loads(out.read_text(), parse_constant=strict_json)
    assert record["status"] == "failed" and "no Levenberg-Marquardt start" in record["message"]
    assert record["error"] is None  # NaN is not JSON: written as null


def strict_json(name):
    raise AssertionError(f"{name} in a JSON file: strict readers refuse it")


def test_a_fit_of_two_points_is_underdetermined_not_converged(tmp_path, capsys):
    """``brdfjax fit two.csv --model ggx`` said ``status converged`` with E of 4.6e-27 %
    and ks = 363 (issue 47, defect 1): it now says underdetermined, why, in one warning
    line, and estimates no uncertainty from it; the JSON carries the status and message."""
    two = tmp_path / "two.csv"
    two.write_text("theta_i,theta_r,phi_r,brdf\n30,20,0,0.31\n60,40,180,0.52\n")
    out = tmp_path / "two.json"
    assert main(["fit", str(two), "--model", "ggx", "--json", str(out)]) == 0
    printed, said = capsys.readouterr()
    assert "ggx model, status underdetermined" in printed
    assert "uncertainty: none, the fit is underdetermined" in printed
    warning = [line for line in said.splitlines() if "UnderdeterminedWarning" in line]
    assert len(warning) == 1 and "2 distinct geometries (theta_i, theta_r, phi_r) for the 4 " \
        "parameters of ggx" in warning[0], said
    record = json.loads(out.read_text())
    assert record["status"] == "underdetermined" and "2 distinct" in record["message"]


def test_numerical_warnings_become_one_line_each(monkeypatch, capsys):
    import brdfjax.commands.data as commands

    def noisy(args):
        np.float64(1e308) ** 2  # RuntimeWarning: overflow, twice
        np.float64(1e308) ** 2
        warnings.warn("old", DeprecationWarning)  # not for users

    monkeypatch.setattr(commands, "run_info", noisy)
    assert main(["info", "x.csv"]) == 0
    err = capsys.readouterr().err
    assert err == "brdfjax info: warning: overflow encountered in scalar power (RuntimeWarning)\n"


@pytest.mark.parametrize("command", [
    ["fit", "{data}", "--plot", "{missing}/fit.png"],
    ["fit", "{data}", "--json", "{tmp}"],
    ["fit", "{data}", "--plot-3d", "{file}/3d.png"],
    ["fit", "{data}", "--uncertainty", "mcmc", "--chain", "{missing}/chain.h5"],
    ["convert", "{data}", "{missing}/out.csv"],
    ["batch", "{data}", "--out", "{missing}/results.csv"],
    ["batch", "{data}", "--out", "{tmp}/results.csv", "--json", "{file}/json"],
    ["demo", "--out", "{file}"],
    ["fit", "{data}", "--plot", "{tmp}/fit.xyz"],  # a format matplotlib does not write
    ["fit", "{data}", "--plot", "{tmp}/fit"],  # no format at all
    ["models", "{data}", "--json", "{missing}/models.json"],
    ["models", "{data}", "--plot", "{tmp}/models.xyz"],
    ["batch", "{data}", "--out", "{tmp}/r.csv", "--wavelength", "all", "--plot", "{tmp}/s.xyz"],
    ["measure", "--port", "/dev/null", "--incidence", "10", "--out", "{missing}/m.csv"],
], ids=lambda command: " ".join(command[:1] + command[2:3]))
def test_an_unwritable_output_fails_before_any_work(command, tmp_path, capsys, monkeypatch):
    import brdfjax.data.formats

    def no_work(*args, **kwargs):
        raise AssertionError("work started before the outputs were checked")

    monkeypatch.setattr(brdfjax.data.formats, "load", no_work)
    (tmp_path / "plain").write_text("a file, not a folder")
    places = {"data": str(DATA / "synthetic" / "white_paint.csv"), "tmp": str(tmp_path),
              "missing": str(tmp_path / "missing"), "file": str(tmp_path / "plain")}
    argv = [part.format(**places) for part in command]
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    given = [part for part in argv if str(tmp_path) in part][-1]  # the bad one comes last
    assert captured.err.startswith(f"brdfjax {argv[0]}: error: ") and given in captured.err
    assert ".brdfjax" not in captured.err and list(tmp_path.glob(".*")) == []


@pytest.mark.parametrize("options, said", [
    (["--export", "t.bsdf", "--export-step", "7"],
     "--export-step 7: give a step in degrees of at most 90 that divides 180"),
    (["--export", "t.bsdf", "--export-step", "180"], "--export-step 180: give a step"),
    (["--export", "t.bsdf", "--export-step", "0"], "--export-step 0: give a step"),
    (["--export", "t.bsdf", "--export-incidences", "30,95"],
     "--export-incidences: 95 deg is not an incidence in [0, 90)"),
])
def test_an_export_grid_is_checked_in_degrees_before_the_fit(options, said, tmp_path, capsys,
                                                             monkeypatch):
    import brdfjax.data.formats

    def no_work(*args, **kwargs):
        raise AssertionError("work started before the export grid was checked")

    monkeypatch.setattr(brdfjax.data.formats, "load", no_work)
    monkeypatch.chdir(tmp_path)
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), *options]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"brdfjax fit: error: {said}") and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_too_few_walkers_are_refused_before_the_fit(tmp_path, capsys, monkeypatch):
    """emcee's walker count is known before the fit (the white paint gives sigma: 5
    coordinates): refused then, and no file written."""
    import brdfjax.fitting.fit

    def no_work(*args, **kwargs):
        raise AssertionError("the fit started before the walkers were checked")

    monkeypatch.setattr(brdfjax.fitting.fit, "fit", no_work)
    data = str(DATA / "synthetic" / "white_paint.csv")
    out = tmp_path / "p.csv"
    assert main(["fit", data, "--uncertainty", "mcmc", "--walkers", "3", "--predict", data,
                 "--predict-out", str(out), "--json", str(tmp_path / "r.json")]) == 1
    assert "emcee needs at least 10 walkers for 5 sampled coordinates, got 3" in (
        capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []
    # with --model auto, before the models are compared (it was refused only after them),
    # for the largest candidate: ggx+ggx, 7 parameters with the sigma of the data
    from brdfjax.prediction import selection

    monkeypatch.setattr(selection, "compare_models", no_work)
    assert main(["fit", data, "--model", "auto", "--uncertainty", "mcmc", "--walkers", "12",
                 "--json", str(tmp_path / "r.json")]) == 1
    assert ("--model auto may choose ggx+ggx: emcee needs at least 14 walkers for 7 sampled "
            "coordinates, got 12") in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, said", [
    (["eval", "--theta-i", "30", "--theta-r", "20:40:0", "--phi-r", "0"],
     "'20:40:0': a range START:STOP:STEP runs upwards with a positive step, e.g. 20:40:1"),
    (["eval", "--theta-i", "30", "--theta-r", "40:20:1", "--phi-r", "0"],
     "'40:20:1': a range START:STOP:STEP runs upwards with a positive step, e.g. 20:40:1"),
    (["eval", "--params", "white_paint", "--theta-i", "30", "--theta-r", "95"],
     ("95 deg: zenith angles lie in [0, 90] deg (a signed in-plane angle t is theta_r = |t|, "
      "with phi_r 180 on the specular side, else 0)")),
    (["fit", "x.csv", "--incidences-3d", "100"], "100 deg: zenith angles lie in [0, 90] deg"),
    (["eval", "--theta-i", "30", "--theta-r", "10:20:nan", "--phi-r", "0"],
     "'10:20:nan': give finite numbers of degrees"),
    (["fit", "x.csv", "--incidences-3d", "nan"], "'nan': give finite numbers of degrees"),
    (["batch", "x.csv", "--out", "r.csv", "--max-generations", "0"], "0: give at least 1"),
    (["batch", "x.csv", "--out", "r.csv", "--starts", "two"], "'two': give a whole number"),
])
def test_a_bad_count_or_range_is_one_usage_error(argv, said, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    assert said in capsys.readouterr().err.strip().splitlines()[-1]


def test_demo_says_whether_it_compiled():
    """`compilations` counts what XLA compiled, not what came from the on-disk cache."""
    import random

    import jax

    from brdfjax.cache import enable
    from brdfjax.commands.fitting import compilations

    enable()
    factor = random.random()  # a function no earlier run has compiled

    def work():
        return jax.jit(lambda x: x * factor + 1)(np.arange(7.0))

    assert compilations(work)[1] == 1
    jax.clear_caches()  # the in-memory cache gone: the next call reads the disk cache
    assert compilations(work)[1] == 0


def test_bound_notes_explain_the_kb_b_trade_and_hint_only_where_widening_helps():
    from brdfjax.commands.fitting import bound_notes

    names = ("kb", "kr", "a", "b", "kd")
    trade, = bound_notes(names, (1e-14, 0.2, 0.05, 32.9, 0.01), {"kb": "lower"})
    assert "product" in trade and "--bound" not in trade and "kb exp(b) = 1.94" in trade
    absent = bound_notes(names, (1e-14, 0.2, 0.5, -3.0, 1e-8), {"kb": "lower", "kd": "lower"})
    assert all("cannot lower E" in text for text in absent)
    wider = bound_notes(names, (5.0, 100.0, 0.5, -150.0, 0.1), {"kr": "upper", "b": "lower"})
    assert all("--bound" in text for text in wider)
    # keyed by names: a model without b gets no degeneracy note
    other, = bound_notes(("kb", "roughness"), (1e-14, 0.3), {"kb": "lower"})
    assert "product" not in other
    # a reflectance at 1, the end of its physical range: no wider bound is offered (it was,
    # and the wider bound --bound f0=0:2 was taken); a narrower box's edge may be widened
    names, limits = ("ks", "alpha", "f0", "kd"), {"f0": (0.0, 1.0)}
    physical, = bound_notes(names, (2.0, 0.36, 1.0, 1e-8), {"f0": "upper"}, limits)
    assert "end of its physical range (0 to 1)" in physical and "--bound" not in physical
    narrow, = bound_notes(names, (2.0, 0.36, 0.5, 1e-8), {"f0": "upper"}, limits)
    assert narrow.endswith("widen it with --bound f0=LO:HI (within its physical range, 0 to 1)")


def test_a_note_never_offers_a_bound_past_a_physical_limit(capsys):
    """Ross-Li's f_geo = 0 at its lower bound was told "widen it with --bound f_geo=LO:HI",
    and --bound f_vol=-1:1 was taken (issue 47, defect 3). In every model, a parameter at a
    bound that is the end of its physical range is told no wider bound exists; at a bound
    inside the range, it is offered a wider one within the range."""
    from brdfjax.commands.fitting import bound_notes
    from brdfjax.models import available, get
    from brdfjax.models.bounds import default_bounds

    for name in available():
        model, box = get(name), default_bounds(get(name))
        limits = {p.name: p.limits for p in model.parameters if p.limits}
        ranges = dict(zip(model.names, zip(box.lower.tolist(), box.upper.tolist())))
        for k, parameter in enumerate(model.parameters):
            for side, bound in (("lower", box.lower[k]), ("upper", box.upper[k])):
                params = np.where(np.arange(model.size) == k, bound, (box.lower + box.upper) / 2)
                note, = bound_notes(model.names, params, {parameter.name: side}, limits, ranges)
                end = parameter.limits and parameter.limits[side == "upper"]
                if end is not None and end == bound:
                    assert "no wider bound exists" in note and "--bound" not in note, note
                elif "--bound" in note and parameter.limits:
                    assert "within its physical range" in note, note
    names, limits = get("ross-li").names, {n: (0.0, float("inf")) for n in get("ross-li").names}
    at_zero, = bound_notes(names, (0.055, 0.08, 0.0), {"f_geo": "lower"}, limits,
                           {n: (0.0, 10.0) for n in names})
    assert at_zero.endswith("the end of its physical range (0 and above): the data ask for "
                            "more than the model can give there; no wider bound exists")
    inside, = bound_notes(names, (0.055, 0.08, 0.1), {"f_geo": "lower"}, limits,
                          {"f_iso": (0.0, 10.0), "f_vol": (0.0, 10.0), "f_geo": (0.1, 10.0)})
    assert inside.endswith("--bound f_geo=LO:HI (within its physical range, 0 and above)")
    assert main(["fit", str(DATA / "synthetic" / "white_paint.csv"), "--model", "ross-li",
                 "--bound", "f_vol=-1:1"]) == 1
    assert ("bound of f_vol: -1 to 1 leaves its physical range, 0 and above"
            in capsys.readouterr().err)


def test_a_bound_past_a_physical_limit_is_refused(capsys):
    """f0, a reflectance, lies within 0 to 1: a --bound past it is refused before any work,
    in every model that has it (a sum's second f0 too); inside it, taken."""
    from brdfjax.models.bounds import make_bounds

    for model, name in (("ggx", "f0"), ("beckmann", "f0"), ("ggx+ggx", "f0_2")):
        with pytest.raises(ValueError, match=rf"bound of {name}: 0 to 2 leaves its physical "
                                             r"range, 0 to 1 \(Schlick's normal-incidence "
                                             r"reflectance\); give a range inside it"):
            make_bounds({name: (0.0, 2.0)}, model=model)
        bounds = make_bounds({name: (0.1, 0.5)}, model=model)
        assert 0.5 in bounds.upper and 0.1 in bounds.lower
    assert main(["fit", str(EC1), "--model", "ggx", "--bound", "f0=0:2"]) == 1
    assert "leaves its physical range" in capsys.readouterr().err


EC1 = REAL / "uaz-loft-rt300s" / "raw" / "ANOPLATE_AnoBlack_EC1_Alum6061_v1o0_20251115.xls"


def test_a_sum_fits_with_its_parameter_names_and_intervals(tmp_path, capsys):
    """--model A+B is a model like any other: the sum's parameter names in the JSON, Laplace intervals."""
    out = tmp_path / "sum.json"
    assert main(["fit", str(EC1), "--model", "ggx+backscatter", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert list(result["params"]) == ["ks", "alpha", "f0", "kd", "kb", "beta"]
    assert result["model"] == "ggx+backscatter" and result["status"] == "converged"
    assert set(result["uncertainty"]["params"]) == set(result["params"])


def test_abg_per_incidence_writes_a_catalog_entry(tmp_path, capsys):
    """One (A, B, g) row per incidence, the TIS checks and FRED's values printed, and the
    entry's rows equal to the fits in the JSON."""
    entry, out = tmp_path / "ec1.txt", tmp_path / "ec1.json"
    assert main(["fit", str(EC1), "--model", "abg", "--per-incidence", "--abg-out", str(entry),
                 "--abg-name", "EC1", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "FRED" in printed and "TIS" in printed
    lines = entry.read_text().splitlines()
    assert lines[0] == "EC1 0.65"  # the RT-300S laser, 650 nm
    rows = json.loads(out.read_text())["abg"]
    assert len(lines) == 1 + len(rows) == 5
    for line, row in zip(lines[1:], rows):
        angle, a, b, g = (float(x) for x in line.split())
        assert angle == row["incidence_deg"]
        np.testing.assert_allclose([a, b, g], [row["A"], row["B"], row["g"]], rtol=1e-7)


def test_abg_out_needs_abg_per_incidence(tmp_path, capsys, monkeypatch):
    """Refused before any work, before the data are read: with --model auto it was
    refused only after the models were compared, a minute later. Nothing is written."""
    import brdfjax.data.formats

    def no_work(*args, **kwargs):
        raise AssertionError("the data were read before the refusal")

    monkeypatch.setattr(brdfjax.data.formats, "load", no_work)
    for options in (["--model", "ggx", "--per-incidence"], ["--model", "abg"],
                    ["--model", "auto", "--predict", str(EC1), "--predict-out",
                     str(tmp_path / "p.csv")]):
        assert main(["fit", str(EC1), *options, "--abg-out", str(tmp_path / "x.txt")]) != 0
        assert "it needs --model abg --per-incidence" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


STEEL_A = REAL / "uaz-loft-rt300s" / "raw" / "NiTE_on_steel_v1o0A_20250915.xls"


def test_the_reader_options_apply_to_the_predict_file_where_its_format_takes_them(
        tmp_path, capsys):
    """``fit X.xls --in-plane --predict grid.csv`` was refused: --in-plane was applied to the
    geometry CSV too. The CSV takes none of the RT-300S options; the prediction is the fitted
    model's (its transcription at the JSON's parameters), at the CSV's geometry. An RT-300S
    --predict file is read in the plane, as the fitted one; a folder is still refused, naming
    the option."""
    grid = tmp_path / "grid.csv"
    angles = np.array([[50.0, r, side] for r in (5.0, 30.0, 60.0) for side in (0.0, 180.0)])
    grid.write_text("theta_i,theta_r,phi_r\n"
                    + "".join(f"{i:g},{r:g},{p:g}\n" for i, r, p in angles))
    out, record = tmp_path / "pred.csv", tmp_path / "fit.json"
    assert main(["fit", str(STEEL_A), "--in-plane", "--model", "ggx", "--uncertainty", "none",
                 "--discrepancy", "none", "--predict", str(grid), "--predict-out", str(out),
                 "--json", str(record)]) == 0, capsys.readouterr().err
    header, *lines = out.read_text().splitlines()
    rows = np.array([[float(v) for v in line.split(",")] for line in lines])
    np.testing.assert_allclose(rows[:, :3], angles)
    params = json.loads(record.read_text())["params"]
    expected = transcription.ggx(*(params[k] for k in ("ks", "alpha", "f0", "kd")),
                                 *np.radians(angles.T))
    np.testing.assert_allclose(rows[:, header.split(",").index("model_brdf")], expected,
                               rtol=1e-6)
    # an RT-300S file takes --in-plane: its 120 in-plane readings, not its 3-D scan
    assert main(["fit", str(STEEL_A), "--in-plane", "--model", "ggx", "--uncertainty", "none",
                 "--discrepancy", "none", "--predict", str(STEEL_A), "--predict-out",
                 str(out)]) == 0
    assert len(out.read_text().splitlines()) == 1 + 120
    capsys.readouterr()
    assert main(["fit", str(STEEL_A), "--in-plane", "--predict", str(tmp_path),
                 "--predict-out", str(out)]) == 1
    assert capsys.readouterr().err.startswith(
        f"brdfjax fit: error: --predict {tmp_path}: is a folder")
