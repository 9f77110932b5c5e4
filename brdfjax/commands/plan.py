"""``brdfjax plan``: choose the next geometries to measure, as a geometry CSV and a
measurement plan (`brdfjax.instrument.design`)."""

from __future__ import annotations

import sys

from brdfjax.commands import add_reader_options, check_writable, reader_options


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "plan", help="choose the next geometries to measure",
        description="Choose --budget geometries to measure next, among --candidates (default: "
                    "the instrument's reachable grid), and order them into a short route for "
                    "the motors. From measurements (MEASURED): the readings that most reduce "
                    "the variance of the model's learned discrepancy summed over --region "
                    "(integrated variance, ALC). From none: a space-filling design (greedy "
                    "maximin). Writes OUT.csv (theta_i,theta_r,phi_r in the order to measure) "
                    "and OUT.toml, a plan for brdfjax measure --plan.")
    p.add_argument("measured", nargs="?", metavar="MEASURED",
                   help="measurements already taken (any format brdfjax reads); leave out "
                        "to start from nothing")
    p.add_argument("--budget", type=int, required=True, metavar="K",
                   help="how many readings to plan")
    p.add_argument("--candidates", metavar="GEOM",
                   help="the geometries to choose among (a file; its values, if any, are "
                        "ignored). Default: incidences 0-80 deg step 10, theta_r 0-85 step "
                        "5, phi_r 0 and 180 (0-180 step 15 when MEASURED is out of the "
                        "plane), less the geometries the instrument cannot reach")
    p.add_argument("--region", metavar="GEOM",
                   help="where the prediction is wanted (a geometry file; default: the "
                        "candidates); every geometry must be within the instrument's reach")
    p.add_argument("--out", required=True, metavar="NEXT",
                   help="writes NEXT.csv and NEXT.toml")
    p.add_argument("--model", default="ggx", metavar="NAME",
                   help="the model whose discrepancy is learned from MEASURED (default ggx; "
                        "as in fit; auto chooses it as fit --model auto --predict does, "
                        "from readings at 3 or more incidences)")
    p.add_argument("--seed", type=int, default=0,
                   help="seeds the fit and the space-filling design (default 0)")
    add_reader_options(p)
    p.set_defaults(run=run_plan)


def run_plan(args) -> None:
    from pathlib import Path

    from brdfjax.data.formats import load, load_geometry, write_atomically
    from brdfjax.data.measurements import DataError
    from brdfjax.instrument.design import check_inputs, instrument_grid, plan

    if args.budget < 1:
        raise ValueError(f"--budget {args.budget}: give the number of readings to plan, a "
                         "whole number of at least 1")
    stem = Path(args.out)
    if stem.suffix.lower() in (".csv", ".toml"):
        stem = stem.with_suffix("")
    csv_path, toml_path = f"{stem}.csv", f"{stem}.toml"
    for path in (csv_path, toml_path):
        check_writable({"--out": path})
    options = reader_options(args)

    def read(label, path, reader):
        try:
            return reader(path, **options)
        except DataError as problem:
            raise ValueError(f"{label}: {problem}") from None

    measured = None if args.measured is None else read("MEASURED", args.measured, load)
    if args.candidates is not None:
        candidates = read("--candidates", args.candidates, load_geometry)
        named = f"--candidates {args.candidates}"
    else:
        candidates = instrument_grid(out_of_plane=measured is not None and not measured.in_plane)
        named = "the instrument's grid"
    region = None if args.region is None else read("--region", args.region, load_geometry)
    names = {"budget": "--budget", "candidates": named, "region": f"--region {args.region}",
             "measured": args.measured, "model": "--model"}
    check_inputs(candidates, args.budget, region=region, measured=measured, model=args.model,
                 names=names)
    if measured is not None:
        from brdfjax.cache import enable

        enable()
    result = plan(measured, candidates, args.budget, region=region, model=args.model,
                  seed=args.seed)
    source = "no measurements" if measured is None else f"{args.measured}"
    comment = (f"written by brdfjax plan from {source}: {len(result)} readings "
               f"({result.method}), about {result.motor_seconds:.0f} s of motor travel")
    write_atomically(csv_path, result.to_csv())
    write_atomically(toml_path, result.instrument_plan().to_toml(comment))
    for line in result.summary():
        print(line)
    print(f"wrote {csv_path} and {toml_path}; measure them with: brdfjax measure --port "
          f"DEVICE --plan {toml_path} --out FILE", file=sys.stderr)
