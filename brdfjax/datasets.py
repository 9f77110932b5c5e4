"""Real BRDF measurements by others, fetched from their public sources.

brdfjax carries no real data: each set is downloaded, file by file, from the public
repository that publishes it, at a pinned commit, and checked against the SHA-256 recorded
in ``datasets.txt`` beside this module (pooch does the download, the check and the cache,
as ``scipy.datasets`` does). The files land unchanged in the user's cache folder
(``pooch.os_cache("brdfjax")``: ``~/.cache/brdfjax`` on Linux), laid out as
``<set>/<folder>/<file>``::

    import brdfjax
    folder = brdfjax.datasets.fetch("nist-germer-ptfe")
    data = brdfjax.load(folder / "PTFE.data.csv", wavelength_nm=532)

A local copy laid out the same way is used instead when the environment variable
``BRDFJAX_DATA`` names its folder (an offline machine, a lab share): nothing is downloaded
then, and a file missing from it is an error that names the folder and the file.

Each set keeps its licence and attribution (`SETS`; the licence file is fetched with the
data): cite the source when you publish with it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

ENVIRONMENT = "BRDFJAX_DATA"
REGISTRY = Path(__file__).with_name("datasets.txt")


@dataclass(frozen=True)
class DataSet:
    """A real data set: what it holds, who measured it, and on what terms."""

    name: str
    title: str
    instrument: str
    license: str
    citation: str


SETS = {s.name: s for s in (
    DataSet("uaz-loft-rt300s",
            "black space coatings (anodize EC1/EC2, NiTE on steel and invar, Aeroglaze, "
            "Singularity, Magic Black) and a Sony IMX455 image sensor at 10 stage rotations; "
            "3-D scans at incidence 10/30/50/70 deg, and 1-degree in-plane legacy scans",
            "J&C RT-300S scatterometer, 650 nm, LOFT group, University of Arizona",
            "MIT (c) 2025 LOFT Group: keep LICENSE and this attribution with every copy",
            "J. P. Krell, M. Duque et al., ua-loft/bsdf-tools (GitHub), commit 30ccb542"),
    DataSet("nist-germer-ptfe",
            "sintered PTFE, the white diffuse reflectance standard: a full out-of-plane grid "
            "at 351/532/633/1064 nm (incidence 0-75 deg) and 1760 random geometries at 532 nm",
            "NIST goniometric scatterometer (T. A. Germer)",
            "US federal government data (public domain in the US)",
            "T. A. Germer, Applied Optics 56 (2017) 9333; as redistributed in "
            "AlexCast/ptfe_eg_error (GitHub), commit ff9fb845"),
    DataSet("starlink-v1p5-scatterworks",
            "Starlink v1.5 chassis deck (white paint, glossy) and solar array (cover glass: "
            "a sharp specular spike); in-plane, incidence 5/41.4/60/75 deg, 1-degree steps",
            "ScatterWorks scatterometer, 532 nm",
            "MIT (c) 2023 Forrest Fankhauser: keep LICENSE and this attribution with every copy",
            "F. Fankhauser, J. A. Tyson, J. Askari, arXiv:2305.11123 (2023); "
            "Forrest-Fankhauser/satellite-optical-brightness (GitHub), commit c6a0011"),
)}


def names() -> list[str]:
    """The names of the sets."""
    return list(SETS)


def files(name: str) -> list[str]:
    """The files of set ``name``, as paths relative to its folder."""
    check_name(name)
    return [path.split("/", 1)[1] for path in _registry() if path.startswith(f"{name}/")]


def fetch(name: str, *, progress: bool = False) -> Path:
    """The folder of set ``name``, every file of it present and checked.

    With ``BRDFJAX_DATA`` set, its ``name`` subfolder (nothing is downloaded; a missing file
    is an error naming the folder and the file). Otherwise each file not yet in the cache is
    downloaded from its source and its SHA-256 checked (a file that fails the check is not
    kept: run again to retry); ``progress`` shows a bar per download.

    Raises:
        ValueError: an unknown name (the message lists the names), a file missing from
            ``BRDFJAX_DATA``, a failed download or a hash mismatch.
    """
    check_name(name)
    local = local_folder()
    if local:
        folder = local / name
        missing = _missing(folder, name)
        if missing:
            raise ValueError(f"{ENVIRONMENT}={os.environ[ENVIRONMENT]}: {folder} has no {missing[0]}"
                             + (f" (and {len(missing) - 1} more files)" if len(missing) > 1
                                else "")
                             + f"; point {ENVIRONMENT} at a folder holding the set '{name}', "
                               "or unset it to download the set")
        return folder
    store = _pooch()
    for path in _registry():
        if path.startswith(f"{name}/"):
            _download(store, path, progress)
    return Path(store.path) / name


def path(name: str, file: str | None = None) -> Path:
    """`fetch` of ``name``, then its folder, or the path of one of its ``file``."""
    folder = fetch(name)
    if file is None:
        return folder
    if file not in files(name):
        raise ValueError(f"set '{name}' has no file {file!r}; it has: {', '.join(files(name))}")
    return folder / file


def local_folder() -> Path | None:
    """The folder ``BRDFJAX_DATA`` names, if it is set."""
    local = os.environ.get(ENVIRONMENT)
    return Path(local).expanduser() if local else None


def is_present(name: str) -> bool:
    """Whether every file of set ``name`` is already here (no download needed), hashes
    not checked."""
    return not _missing((local_folder() or cache_folder()) / name, name)


def _missing(folder: Path, name: str) -> list[str]:
    """The files of set ``name`` that ``folder`` lacks."""
    return [f for f in files(name) if not (folder / f).is_file()]


def cache_folder() -> Path:
    """Where downloaded sets are kept (the user's cache folder)."""
    import pooch

    return Path(pooch.os_cache("brdfjax"))


def check_name(name: str) -> None:
    """Refuse a name that is not a set's, listing the sets."""
    if name not in SETS:
        raise ValueError(f"no data set named {name!r}; the sets are: {', '.join(SETS)}")


def _registry() -> dict[str, tuple[str, str]]:
    """Path in the cache -> (``sha256:`` hash, source address), from ``datasets.txt``."""
    entries = {}
    for line in REGISTRY.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            path, digest, url = line.split()
            entries[path] = (digest, url)
    return entries


def _pooch():
    import pooch

    registry = _registry()
    return pooch.create(path=cache_folder(), base_url="",
                        registry={p: digest for p, (digest, _) in registry.items()},
                        urls={p: url for p, (_, url) in registry.items()}, retry_if_failed=2)


def _download(store, path: str, progress: bool) -> None:
    url = store.get_url(path)
    try:
        store.fetch(path, progressbar=progress)
    except ValueError as error:  # pooch: the hash of the download does not match
        raise ValueError(f"{path}: the file downloaded from {url} is not the one recorded "
                         f"({error}); it was not kept: run the command again to retry, or "
                         f"set {ENVIRONMENT} to a local copy") from error
    except OSError as error:  # no network, a refused connection, an HTTP error
        raise ValueError(f"{path}: could not download it from {url} ({error}); are you "
                         f"offline? Set {ENVIRONMENT} to a folder holding a copy of the sets "
                         "(brdfjax datasets list names them)") from error
