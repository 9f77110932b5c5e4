"""brdfjax.datasets: real sets fetched over HTTP, hashed, cached, or read from BRDFJAX_DATA.

The downloads are real: a local HTTP server (this machine reaches no other) serves the
project's shared copy of the files, at the addresses a temporary registry gives them.
"""

import hashlib
import threading
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

import pytest
from conftest import REAL

from brdfjax import datasets
from brdfjax.cli import main

SET = "starlink-v1p5-scatterworks"  # three small files


def sha256(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_the_registry_records_every_file_of_the_copy_with_its_hash():
    """Every file of the local copy (the sources' files unchanged) is in the registry with
    its SHA-256, and every registered file is in the copy."""
    for name in datasets.names():
        registered = set(datasets.files(name))
        here = {str(p.relative_to(REAL / name)) for p in (REAL / name).rglob("*")
                if p.is_file() and "derived" not in p.parts
                and p.name not in ("README.md", "SOURCE.txt")}
        assert registered == here, name
        for line in datasets.REGISTRY.read_text().splitlines():
            if line.startswith(f"{name}/"):
                path, digest, url = line.split()
                assert digest == "sha256:" + sha256(REAL / path), path
                assert url.startswith("https://raw.githubusercontent.com/"), url


@pytest.fixture
def server(tmp_path, monkeypatch):
    """A local HTTP server of the shared copy, a registry whose addresses point at it, and
    an empty cache folder; yields the files served and the requests made."""
    requested = []

    class Handler(SimpleHTTPRequestHandler):
        def log_message(self, *args):
            requested.append(self.path)

    served = tmp_path / "served"
    served.mkdir()
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), partial(Handler, directory=str(served)))
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{httpd.server_address[1]}"
    lines = []
    for line in datasets.REGISTRY.read_text().splitlines():
        if line.startswith(f"{SET}/"):
            path, digest, _ = line.split()
            (served / path).parent.mkdir(parents=True, exist_ok=True)
            (served / path).write_bytes((REAL / path).read_bytes())
            line = f"{path} {digest} {base}/{path}"
        lines.append(line)
    registry = tmp_path / "registry.txt"
    registry.write_text("\n".join(lines) + "\n")
    monkeypatch.setattr(datasets, "REGISTRY", registry)
    monkeypatch.delenv(datasets.ENVIRONMENT, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    yield served, requested
    httpd.shutdown()


def test_fetch_downloads_checks_and_caches_a_set(server, tmp_path):
    _, requested = server
    folder = datasets.fetch(SET)
    assert folder == tmp_path / "cache" / "brdfjax" / SET
    for name in datasets.files(SET):
        assert (folder / name).read_bytes() == (REAL / SET / name).read_bytes()
    assert len(requested) == 3 and datasets.is_present(SET)
    assert datasets.fetch(SET) == folder and len(requested) == 3  # kept: nothing fetched
    assert datasets.path(SET, "chassis_brdf.csv") == folder / "chassis_brdf.csv"


def test_a_corrupted_download_is_refused_not_kept_and_a_retry_works(server, tmp_path):
    served, _ = server
    target = served / SET / "chassis_brdf.csv"
    good = target.read_bytes()
    target.write_bytes(good.replace(b"0", b"1", 1))
    with pytest.raises(ValueError, match="is not the one recorded.*run the command again"):
        datasets.fetch(SET)
    assert not (tmp_path / "cache" / "brdfjax" / SET / "chassis_brdf.csv").exists()
    target.write_bytes(good)
    assert (datasets.fetch(SET) / "chassis_brdf.csv").read_bytes() == good


def test_offline_says_so_and_names_the_variable(server, monkeypatch, tmp_path):
    registry = datasets.REGISTRY.read_text().replace("http://127.0.0.1:", "http://127.0.0.1:1#")
    (tmp_path / "offline.txt").write_text(registry)
    monkeypatch.setattr(datasets, "REGISTRY", tmp_path / "offline.txt")
    with pytest.raises(ValueError, match="could not download.*offline.*BRDFJAX_DATA"):
        datasets.fetch(SET)


def test_a_local_copy_without_the_set_names_the_folder_and_the_file(tmp_path, monkeypatch,
                                                                    capsys):
    (tmp_path / SET).mkdir()
    (tmp_path / SET / "LICENSE").write_text("MIT")
    monkeypatch.setenv(datasets.ENVIRONMENT, str(tmp_path))
    assert main(["datasets", "path", SET]) == 1
    said = capsys.readouterr().err
    assert f"{tmp_path / SET} has no chassis_brdf.csv (and 1 more files)" in said
    assert "BRDFJAX_DATA" in said


def test_an_unknown_name_lists_the_sets_before_any_download(capsys):
    assert main(["datasets", "fetch", SET, "nosuch"]) == 1
    said = capsys.readouterr()
    assert "no data set named 'nosuch'; the sets are: " + ", ".join(datasets.names()) in said.err
    assert said.out == ""  # the good name was not fetched first
