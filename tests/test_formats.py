"""brdfjax's CSV format, and the message and exit code of every kind of bad input."""

import os
import re
import stat
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA

from brdfjax.cli import main
from brdfjax.data.formats import load, replace_atomically, save, write_atomically
from brdfjax.data.measurements import DataError, Measurements
from brdfjax.data.synthetic import paper_sample

HEADER = "theta_i,theta_r,phi_r,brdf\n"
GOOD_ROWS = "".join(f"{ti},{tr},180,{0.1 + 0.001 * tr}\n" for ti in (10, 30) for tr in (0, 20, 40))


def test_round_trip_keeps_everything(tmp_path):
    data = paper_sample("khaki_paint", seed=7)
    save(data, tmp_path / "k.csv")
    back = load(tmp_path / "k.csv")
    for name in ("theta_i", "theta_r", "phi_r", "brdf", "sigma"):
        np.testing.assert_allclose(getattr(back, name), getattr(data, name), rtol=1e-9,
                                   atol=1e-12)
    assert back.metadata["sample"] == "khaki_paint"
    assert back.metadata["source"].startswith("SYNTHETIC")


def test_minimal_form_loads(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text(HEADER + GOOD_ROWS)
    data = load(path)
    assert len(data) == 6 and data.sigma is None and data.in_plane
    np.testing.assert_allclose(np.degrees(data.phi_r), 180)


def test_columns_in_any_order_with_weight(tmp_path):
    path = tmp_path / "w.csv"
    path.write_text("brdf,phi_r,theta_r,theta_i,weight\n0.2,0,30,10,2\n0.3,180,30,10,1\n")
    data = load(path)
    np.testing.assert_allclose(data.brdf, [0.2, 0.3])
    np.testing.assert_allclose(data.weights, [2, 1])
    np.testing.assert_allclose(np.degrees(data.theta_i), 10)


BAD = {
    "empty": ("", "empty file"),
    "only comments": ("# sample: x\n", "empty file"),
    "header only": (HEADER, "no measurements"),
    "missing column": ("theta_i,theta_r,brdf\n10,20,0.1\n", "missing column phi_r"),
    "no header": ("10,20,180,0.1\n", "first line is data"),
    "non-numeric cell": (HEADER + "10,20,180,abc\n", ":2: brdf = 'abc' is not a number"),
    "short row": (HEADER + "10,20,180\n", ":2: 3 cells"),
    "NaN": (HEADER + GOOD_ROWS + "10,60,180,nan\n", ":8: brdf is nan"),
    "inf": (HEADER + GOOD_ROWS + "10,60,180,inf\n", ":8: brdf is inf"),
    "negative brdf": (HEADER + GOOD_ROWS + "10,60,180,-0.05\n", ":8: brdf = -0.05 is negative"),
    "angle above 90": (HEADER + GOOD_ROWS + "10,95,180,0.1\n", ":8: theta_r = 95 deg is outside"),
    "signed angle": (HEADER + GOOD_ROWS + "10,-30,0,0.1\n", ":8: theta_r = -30 deg"),
    "azimuth past a turn": (HEADER + GOOD_ROWS + "10,30,400,0.1\n",
                            ":8: phi_r = 400 deg is beyond one turn"),
    "radians": (HEADER + "".join(f"0.5,{t},3.14159,0.1\n" for t in (0.1, 0.4, 0.8, 1.2)),
                "look like radians"),
    "brdf 1e308": (HEADER + GOOD_ROWS + "10,60,180,1e308\n", ":8: brdf = 1e+308 is an outlier"),
    "brdf 1e30": (HEADER + GOOD_ROWS + "10,60,180,1e30\n", ":8: brdf = 1e+30 is an outlier"),
    "unknown column": ("theta_i,theta_r,phi_r,brdf,colour\n10,0,0,1,2\n", "unknown column"),
}


@pytest.mark.parametrize("text,message", BAD.values(), ids=list(BAD))
def test_bad_file_gets_a_clear_error_and_exit_1(tmp_path, capsys, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=re.escape(message)):
        load(path)
    out = tmp_path / "result.json"
    assert main(["fit", str(path), "--json", str(out)]) == 1
    err = capsys.readouterr().err
    assert "bad.csv" in err and message.split(":")[-1].strip()[:12] in err
    assert not out.exists()  # nothing half-written


def test_unknown_format_and_missing_file(tmp_path, capsys):
    (tmp_path / "x.txt").write_text("hello")
    assert main(["info", str(tmp_path / "x.txt")]) == 1
    assert "unknown format '.txt'" in capsys.readouterr().err
    assert main(["info", str(tmp_path / "none.csv")]) == 1
    assert "no such file" in capsys.readouterr().err
    (tmp_path / "y.csv").write_text("theta_i,theta_r,phi_r,brdf\n10,20,180,0.5\n")
    assert main(["info", str(tmp_path / "y.csv"), "--blank", "b.xls"]) == 1  # not a TypeError
    assert capsys.readouterr().err.startswith(
        f"brdfjax info: error: {tmp_path / 'y.csv'}: --blank does not apply to this file "
        "(csv format)")
    assert main(["fit", str(tmp_path)]) == 1  # a folder is not missing: say what to do
    assert capsys.readouterr().err == (
        f"brdfjax fit: error: {tmp_path}: is a folder, not a file (give one of its files; "
        "brdfjax batch FOLDER --out RESULTS.csv fits every file of a folder)\n")


def test_held_out_validation_needs_two_incidences(tmp_path, capsys):
    path = tmp_path / "one.csv"
    path.write_text(HEADER + "".join(f"30,{t},180,0.1\n" for t in range(0, 80, 5)))
    assert main(["fit", str(path), "--validate-incidence", "30"]) == 1
    assert "at least two incidence angles" in capsys.readouterr().err
    assert main(["fit", str(path), "--validate-incidence", "45"]) == 1
    assert "incidence(s) 45 deg not in the data" in capsys.readouterr().err


def test_errors_name_the_file_read_not_the_source_it_records(tmp_path, capsys):
    # A converted CSV records where its data came from; an error is about the CSV itself.
    path = tmp_path / "converted.csv"
    path.write_text("# source: original.xls\n" + HEADER
                    + "".join(f"{i},{t},180,0.1\n" for i in (10, 30) for t in range(0, 80, 5)))
    assert main(["fit", str(path), "--validate-incidence", "45"]) == 1
    assert capsys.readouterr().err.startswith(f"brdfjax fit: error: {path}: held-out incidence")
    data = load(path)
    assert (data.path, data.metadata["source"]) == (str(path), "original.xls")
    for name in ("again.csv", "again.astm"):  # the path is the reader's, not written
        save(data, tmp_path / name)
        assert str(path) not in (tmp_path / name).read_text()
        assert load(tmp_path / name).path == str(tmp_path / name)


def test_measurements_reject_mismatched_lengths():
    with pytest.raises(ValueError, match="theta_r has 2 values"):
        Measurements([0.1, 0.2, 0.3], [0.1, 0.2], [0, 0, 0], [1, 1, 1])


@pytest.fixture
def umask():
    """Set the process umask for one test, and put the old one back."""
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_outputs_get_the_mode_the_umask_gives(tmp_path, umask, mask, mode):
    umask(mask)
    write_atomically(tmp_path / "new.json", "{}\n")
    replace_atomically(tmp_path / "new.png", lambda path: Path(path).write_bytes(b"png"))
    main(["convert", str(DATA / "synthetic" / "cement.csv"), str(tmp_path / "c.bsdf")])
    for name in ("new.json", "new.png", "c.bsdf"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == mode, name


def test_a_replaced_file_keeps_its_mode_and_a_failed_write_leaves_nothing(tmp_path, umask):
    target = tmp_path / "kept.csv"
    target.write_text("old\n")
    target.chmod(0o640)
    write_atomically(target, "new\n")
    assert target.read_text() == "new\n" and stat.S_IMODE(target.stat().st_mode) == 0o640

    def fails(path):
        Path(path).write_text("half")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        replace_atomically(target, fails)
    with pytest.raises(RuntimeError):
        replace_atomically(tmp_path / "never.csv", fails)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.csv"]
    assert target.read_text() == "new\n"
    with pytest.raises(OSError, match=f"cannot write {tmp_path / 'missing' / 'x.png'}: "):
        replace_atomically(tmp_path / "missing" / "x.png", fails)
