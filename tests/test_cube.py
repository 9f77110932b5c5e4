"""``brdfjax batch CUBE.h5``: real HDF5 files in and out, single-fit results, a clear error
for a bad cube, a run killed with SIGKILL and resumed, other options refused, Dask."""

import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from brdfjax.data.formats.cube import Cube, write_cube
from brdfjax.fitting.fit import fit
from brdfjax.models.paper import PAPER_SAMPLES, brdf

h5py = pytest.importorskip("h5py")

SMALL = {"population_size": 64, "max_generations": 15, "starts": 8, "max_steps": 40}
CLI_SMALL = [f"--{k.replace('_', '-')}={v}" for k, v in SMALL.items()]
COUNT = 12


def geometry():
    """48 points: four incidences, a 12-angle in-plane scan each (no exact specular)."""
    theta_i = np.repeat([10.0, 30.0, 45.0, 60.0], 12)
    theta_r = np.tile(np.linspace(-66, 66, 12), 4)
    return theta_i, np.abs(theta_r), np.where(theta_r < 0, 180.0, 0.0)


def values(count, seed=0):
    """Five-parameter BRDFs of perturbed paper samples, 2.5 % noise, (count, 48)."""
    rng = np.random.default_rng(seed)
    angles = np.radians(geometry())
    names = list(PAPER_SAMPLES)
    out = np.empty((count, angles.shape[1]))
    for k in range(count):
        params = np.array(PAPER_SAMPLES[names[k % len(names)]])
        params = params * np.exp(0.1 * rng.standard_normal(5))
        out[k] = np.asarray(brdf(params, *angles)) * (1 + 0.025 * rng.standard_normal(48))
    return out


@pytest.fixture(scope="module")
def cube(tmp_path_factory):
    """A shared-geometry cube: one sample with two missing readings, one with none left."""
    path = tmp_path_factory.mktemp("cube") / "cube.h5"
    brdf_values = values(COUNT)
    brdf_values[3, [5, 17]] = np.nan
    brdf_values[7] = np.nan
    write_cube(path, *geometry(), brdf_values, sample=[f"pixel {k}" for k in range(COUNT)])
    return path


def command(cube, out, *extra):
    return [sys.executable, "-m", "brdfjax.cli", "batch", str(cube), "--out", str(out),
            "--chunk-size=2", *CLI_SMALL, *extra]


def read(path) -> dict:
    with h5py.File(path, "r") as results:
        return {name: results[name][...] for name in results} | {
            f"attr {k}": v for k, v in results.attrs.items()}


@pytest.fixture(scope="module")
def reference(cube, environment, tmp_path_factory):
    out = tmp_path_factory.mktemp("reference") / "results.h5"
    done = subprocess.run(command(cube, out), env=environment, capture_output=True, text=True,
                          timeout=600, check=False)
    return out, done


def test_every_sample_gets_its_single_fit(cube, reference):
    """E of every fitted sample equals brdfjax.fit of that sample (same seed) to 1e-9; the
    sample without readings fails alone and says why; the names are copied."""
    out, done = reference
    assert done.returncode == 1, done.stderr  # the empty sample
    assert f"{COUNT - 1} of {COUNT} fitted" in done.stderr
    table = read(out)
    assert set(table) >= {"kb", "kr", "a", "b", "kd", "error", "status", "message", "sample"}
    assert table["attr model"] == "five"
    assert [s.decode() for s in table["sample"]] == [f"pixel {k}" for k in range(COUNT)]
    status = table["status"].astype(str)
    assert status[7] == "failed" and "has no readings" in table["message"][7].decode()
    assert np.isnan(table["error"][7]) and np.isnan(table["kb"][7])
    with Cube(cube) as opened:
        samples = opened.read(np.arange(COUNT))
    assert len(samples[3]) == 46  # the two missing readings left out
    for k in (0, 3, 10):
        single = fit(samples[k], **SMALL)
        assert table["error"][k] == pytest.approx(single.error, rel=1e-9)
        assert status[k] == single.status
        assert table["kd"][k] == pytest.approx(single.params.kd, rel=1e-6)
    assert not out.with_name("results.h5.parts").exists()  # the journal is gone


@pytest.mark.timeout(600)
def test_killed_halfway_and_resumed_loses_and_duplicates_nothing(cube, reference, environment,
                                                                  tmp_path):
    out = tmp_path / "results.h5"
    parts = tmp_path / "results.h5.parts"
    process = subprocess.Popen(command(cube, out), env=environment,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 400
    while len(list(parts.glob("*.npz"))) < 2 and process.poll() is None:
        assert time.monotonic() < deadline, "no chunk journalled in 400 s"
        time.sleep(0.002)
    process.send_signal(signal.SIGKILL)
    assert process.wait(timeout=60) == -signal.SIGKILL
    kept = len(list(parts.glob("*.npz")))
    assert 2 <= kept < COUNT // 2 and not out.exists(), "the run ended before it was killed"
    resumed = subprocess.run(command(cube, out), env=environment, capture_output=True,
                             text=True, timeout=600, check=False)
    assert f"{2 * kept} of {COUNT} samples already done" in resumed.stderr, resumed.stderr
    assert resumed.returncode == 1
    final, whole = read(out), read(reference[0])
    assert final.keys() == whole.keys()
    for name in final:
        np.testing.assert_array_equal(final[name], whole[name], err_msg=name)


def test_a_rerun_with_other_options_is_refused(cube, reference, tmp_path, capsys):
    from brdfjax.cli import main

    out = tmp_path / "results.h5"
    out.write_bytes(reference[0].read_bytes())
    assert main(command(cube, out, "--seed", "5")[3:]) == 1
    said = capsys.readouterr().err
    assert "was fitted with other options (seed: 0 there, 5 here)" in said, said
    assert main(command(cube, out)[3:]) == 1  # the same: nothing to fit, the failure again
    assert f"{COUNT} of {COUNT} samples already done; nothing left" in capsys.readouterr().err
    bigger = tmp_path / "bigger.h5"
    write_cube(bigger, *geometry(), values(COUNT + 2))
    assert main(command(bigger, out)[3:]) == 1  # another cube: its rows are not these
    said = capsys.readouterr().err
    assert f"samples: {COUNT} there, {COUNT + 2} here" in said and "cube: " in said, said


@pytest.mark.parametrize(("change", "expected"), [
    ("drop theta_r", "no dataset theta_r"),
    ("brdf 1-D", "brdf has shape (12,), not (N, P)"),
    ("phi_r wrong", "phi_r has shape (47,); brdf is (12, 48), so give (12, 48) or (48,)"),
    ("not hdf5", "cannot be read as HDF5"),
    # each of the 12 samples failed on its own, with only "see message in out.h5", where
    # fit refuses the same file at once (issue 47, defect 4)
    ("radians", ("(the angles every sample shares): all zenith angles are at most 1.1519 "
                 "deg (they look like radians; files hold degrees")),
])
def test_a_bad_cube_is_one_clear_error(tmp_path, capsys, change, expected):
    from brdfjax.cli import main

    path = tmp_path / "bad.h5"
    theta_i, theta_r, phi_r = geometry()
    brdf_values = values(COUNT)
    if change == "not hdf5":
        path.write_text("theta_i,theta_r,phi_r,brdf\n")
    else:
        if change == "radians":
            theta_i, theta_r, phi_r = np.radians([theta_i, theta_r, phi_r])
        write_cube(path, theta_i, theta_r, phi_r[:47] if change == "phi_r wrong" else phi_r,
                   brdf_values[:, 0] if change == "brdf 1-D" else brdf_values)
        if change == "drop theta_r":
            with h5py.File(path, "a") as cube:
                del cube["theta_r"]
    assert main(["batch", str(path), "--out", str(tmp_path / "out.h5")]) == 1
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and str(path) in said[0] and expected in said[0], said


def test_a_sample_of_few_readings_is_underdetermined_and_one_of_none_says_so(tmp_path, capsys):
    """A sample with 118 of its 120 readings NaN came back converged with E = 4e-31, and one
    with none was told "the file has a header but no data lines" (issue 47, defects 1 and
    4): 2 readings for 5 parameters are underdetermined in the status column, with why, and
    in the summary line; a sample without readings says so."""
    from brdfjax.cli import main
    from brdfjax.cluster import fit_chunk
    from brdfjax.fitting.fit import UnderdeterminedWarning

    path, out = tmp_path / "sparse.h5", tmp_path / "results.h5"
    brdf_values = values(3)
    brdf_values[1, 2:] = np.nan
    brdf_values[2] = np.nan
    write_cube(path, *geometry(), brdf_values)
    assert main(command(path, out)[3:]) == 1  # the empty sample failed
    said = capsys.readouterr().err
    assert ("1 of 3 fitted; 1 underdetermined (no more distinct geometries than the 5 "
            f"parameters of five: their parameters are not determined; status and message in "
            f"{out}); 1 failed") in said, said
    table = read(out)
    assert [s.decode() for s in table["status"]][1:] == ["underdetermined", "failed"]
    assert table["status"][0].decode() in ("converged", "max_steps")
    messages = [m.decode() for m in table["message"]]
    assert messages[1].startswith("underdetermined: 2 distinct geometries (theta_i, theta_r, "
                                  "phi_r) for the 5 parameters of five")
    assert messages[2] == ("sparse.h5[2]: the sample has no readings (every reading is NaN or "
                           "none was given: nothing to fit)")
    with Cube(path) as cube, pytest.warns(UnderdeterminedWarning, match="samples with no more"):
        summaries = fit_chunk(cube.read([0, 1, 2]), SMALL)  # as with --uncertainty: the same
    assert [s["status"] for s in summaries][1:] == ["underdetermined", "failed"]


def test_per_sample_geometry_reads_each_row(tmp_path):
    """Angles (N, P) give each sample its own geometry; NaN angles drop the reading."""
    theta_i, theta_r, phi_r = geometry()
    rows = np.stack([theta_r, theta_r + 1.0])
    rows[1, 0] = np.nan
    path = tmp_path / "rows.h5"
    write_cube(path, theta_i, rows, phi_r, values(2))
    with Cube(path) as cube:
        assert not cube.shares_geometry
        first, second = cube.read([0, 1])
    np.testing.assert_allclose(np.degrees(first.theta_r), theta_r)
    np.testing.assert_allclose(np.degrees(second.theta_r), theta_r[1:] + 1.0)
    assert first.name == "rows.h5[0]"


def test_a_netcdf4_cube_reads_as_its_hdf5_twin(tmp_path):
    """The same schema written as NetCDF-4 by the NetCDF library itself (netCDF4, on
    libnetcdf: dimensions, a fill value for missing readings, variable-length strings)
    reads into the same samples as the HDF5 cube of the same arrays."""
    netcdf = pytest.importorskip("netCDF4")
    brdf_values = values(3)
    brdf_values[1, 4] = np.nan
    names = ["alpha", "beta", "gamma"]
    hdf5, nc = tmp_path / "twin.h5", tmp_path / "twin.nc"
    write_cube(hdf5, *geometry(), brdf_values, sample=names)
    with netcdf.Dataset(nc, "w", format="NETCDF4") as out:
        out.createDimension("sample", 3)
        out.createDimension("point", 48)
        for name, angles in zip(("theta_i", "theta_r", "phi_r"), geometry()):
            out.createVariable(name, "f8", ("point",))[:] = angles
        brdf_var = out.createVariable("brdf", "f8", ("sample", "point"), fill_value=np.nan)
        brdf_var[:] = np.ma.masked_invalid(brdf_values)
        out.createVariable("sample", str, ("sample",))[:] = np.array(names, dtype=object)
    with Cube(hdf5) as first, Cube(nc) as second:
        assert second.shares_geometry and second.count == 3
        for one, other in zip(first.read([0, 1, 2]), second.read([0, 1, 2])):
            assert other.name == one.name
            for field in ("theta_i", "theta_r", "phi_r", "brdf"):
                np.testing.assert_array_equal(getattr(other, field), getattr(one, field))
        assert [len(x) for x in second.read([0, 1])] == [48, 47]  # the missing one dropped


@pytest.mark.timeout(600)
def test_dask_fits_the_cube_chunk_by_chunk(cube, reference, dask_scheduler, tmp_path, capsys):
    from brdfjax.cli import main

    out = tmp_path / "results.h5"
    code = main(command(cube, out, "--scheduler", dask_scheduler)[3:])
    assert code == 1 and f"{COUNT - 1} of {COUNT} fitted" in capsys.readouterr().err
    final, whole = read(out), read(reference[0])
    assert set(final) == set(whole)
    for name in final:  # the workers run XLA as the local run does (`single_threaded`)
        np.testing.assert_array_equal(final[name], whole[name], err_msg=name)


def test_a_block_with_uncertainty_keeps_its_fits_and_adds_their_std(cube):
    """A cube's block with ``--uncertainty laplace`` goes through the per-sample results
    (the Laplace approximation needs them): the same numbers as the table formed at once (E to
    rounding),
    with each fitted sample's standard deviations, and none for the failed one."""
    from brdfjax.cluster import fit_chunk, fit_cube_chunk

    with Cube(cube) as opened:
        samples = opened.read([0, 7])
    plain = fit_cube_chunk(samples, SMALL)
    laplace = fit_cube_chunk(samples, {**SMALL, "uncertainty": "laplace"})
    for name in ("params", "status", "message"):
        np.testing.assert_array_equal(laplace[name], plain[name], err_msg=name)
    np.testing.assert_allclose(laplace["error"], plain["error"], rtol=1e-13)  # rounding
    assert list(plain["status"]) == ["converged", "failed"]
    assert np.all(np.isfinite(laplace["std"][0])) and np.all(np.isnan(laplace["std"][1]))
    (summary, _) = fit_chunk(samples, {**SMALL, "uncertainty": "laplace"})
    np.testing.assert_array_equal(laplace["std"][0], list(summary["std"].values()))
