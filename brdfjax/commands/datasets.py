"""The ``datasets`` command: the real data sets, listed, fetched from their sources, located."""

from __future__ import annotations


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "datasets", help="list, fetch and locate the real data sets",
        description="Real BRDF measurements by others, downloaded from their public sources "
                    "at pinned commits, checked against recorded SHA-256 hashes and kept in "
                    "the user's cache folder (or read from the folder BRDFJAX_DATA names).")
    actions = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    listing = actions.add_parser("list", help="the sets: what, instrument, licence, where",
                                 description="Each set with its content, instrument, licence "
                                             "and citation, and whether it is here yet.")
    listing.set_defaults(run=run_list)
    fetch = actions.add_parser("fetch", help="download sets (all without a name)",
                               description="Download the named sets (every set without a "
                                           "name) and print their folders.")
    fetch.add_argument("names", nargs="*", metavar="NAME", help="set names (brdfjax datasets "
                                                                "list)")
    fetch.set_defaults(run=run_fetch)
    path = actions.add_parser("path", help="the folder of a set, or of one of its files",
                              description="Print the folder of set NAME (fetched first if "
                                          "needed), or the path of one of its files.")
    path.add_argument("name", metavar="NAME", help="a set name (brdfjax datasets list)")
    path.add_argument("file", nargs="?", metavar="FILE",
                      help="a file of the set, as its folder/name (e.g. raw/notes.txt)")
    path.set_defaults(run=run_path)


def run_list(args) -> None:
    from brdfjax import datasets

    local = datasets.local_folder()
    print(f"sets read from {local} ({datasets.ENVIRONMENT})" if local else
          f"sets kept in {datasets.cache_folder()} (set {datasets.ENVIRONMENT} to use a "
          "local copy instead)")
    for name, s in datasets.SETS.items():
        print(f"\n{name}  [{'here' if datasets.is_present(name) else 'not fetched'}, "
              f"{len(datasets.files(name))} files]\n  {s.title}\n  instrument: {s.instrument}"
              f"\n  licence: {s.license}\n  cite: {s.citation}")


def run_fetch(args) -> None:
    from brdfjax import datasets

    for name in args.names:
        datasets.check_name(name)  # every name checked before any download
    for name in args.names or datasets.names():
        print(f"{name}: {datasets.fetch(name, progress=True)}")


def run_path(args) -> None:
    from brdfjax import datasets

    print(datasets.path(args.name, args.file))
