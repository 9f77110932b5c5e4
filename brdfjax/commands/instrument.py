"""Commands that drive a goniometer: ``measure`` and ``instrument simulate``."""

from __future__ import annotations

import sys

from brdfjax.commands import (
    add_model_option,
    add_reader_options,
    angles,
    check_writable,
    parameters,
    positive_int,
    reader_options,
)

PLAN_OPTIONS = ("theta_r_step", "theta_r_max", "azimuth", "average", "integration_ms",
                "beam_margin")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "measure", help="measure BRDF on the instrument and write a file that fit reads",
        description="Run a measurement plan on the goniometer at --port: each geometry is "
                    "read on the sample and on the PTFE reference plate and converted by "
                    "Eq. (7)-(8). Every reading goes to a journal first; running the same "
                    "command again resumes an interrupted measurement.")
    p.add_argument("--port", required=True, metavar="DEVICE",
                   help="the instrument's serial device (the simulator prints its path)")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--plan", metavar="PLAN", help="a TOML measurement plan")
    what.add_argument("--incidence", type=angles, metavar="DEG",
                      help="incidence angles for an in-plane scan, e.g. 10,30,50")
    p.add_argument("--out", required=True, metavar="FILE", help="the measurement file (.csv)")
    p.add_argument("--journal", metavar="FILE",
                   help="the journal (default: FILE with the suffix .journal.jsonl)")
    p.add_argument("--reference-reflectance", type=float, default=0.99, metavar="RHO",
                   help="hemispherical reflectance of the PTFE reference plate at the "
                        "wavelength (default 0.99)")
    p.add_argument("--sample", help="the sample's name, kept in the file (default: the name "
                                    "of --out without its suffix: khaki.csv -> khaki)")
    p.add_argument("--baud", type=int, default=115200, help="line speed (default 115200)")
    p.add_argument("--timeout", type=float, default=1.0, metavar="SECONDS",
                   help="wait for a reply before resending (default 1)")
    p.add_argument("--retries", type=int, default=5, help="resends per command (default 5)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    scan = p.add_argument_group("in-plane scan (with --incidence; a plan file has its own)")
    scan.add_argument("--theta-r-step", type=float, metavar="DEG",
                      help="reflection zenith step (default 1)")
    scan.add_argument("--theta-r-max", type=float, metavar="DEG",
                      help="sweep the signed reflection zenith from -MAX to MAX (default 85)")
    scan.add_argument("--azimuth", type=angles, metavar="DEG",
                      help="detector-arm azimuths, motor A (default 0: in plane)")
    scan.add_argument("--average", type=positive_int,
                      help="integrations per reading (default 5)")
    scan.add_argument("--integration-ms", type=float, help="per integration (default 20)")
    scan.add_argument("--beam-margin", type=float, metavar="DEG",
                      help="skip geometries with the detector this close to the source "
                           "(default 5)")
    adaptive = p.add_argument_group(
        "adaptive (--adaptive): read what the prediction over the plan needs")
    adaptive.add_argument("--adaptive", action="store_true",
                          help="a closed loop: a space-filling start, then fit, predict over "
                               "the plan's geometries and read the batch that most narrows "
                               "the prediction, until --target-width or a budget is reached")
    options = []  # the adaptive options but --adaptive itself, for "only with --adaptive"

    def option(*names, **settings):
        options.append(adaptive.add_argument(*names, **settings))

    option("--target-width", type=float, default=10.0, metavar="PERCENT",
           help="stop when the median calibrated 95 %% half-width over the "
                "plan's geometries is at most this, in %% (default 10)")
    option("--start", type=int, default=20, metavar="N",
           help="readings of the space-filling start (default 20)")
    option("--batch", type=int, default=10, metavar="N",
           help="readings planned per round (default 10)")
    option("--max-readings", type=int, metavar="N",
           help="stop after this many readings (checked between rounds)")
    option("--max-minutes", type=float, metavar="MIN",
           help="stop after this much instrument time (checked between rounds)")
    option("--candidates", metavar="GEOM",
           help="the geometries that may be read (a file; default: the plan's)")
    option("--model", default="ggx", metavar="NAME",
           help="the model that predicts, as in fit (default ggx; auto: the "
                "one brdfjax models recommends, chosen each round)")
    option("--seed", type=int, default=0,
           help="seeds the start, the fits and the plans (default 0)")
    option("--plot", metavar="PNG",
           help="the figure of width against readings (default: FILE with "
                "the suffix .adaptive.png)")
    p.set_defaults(run=run_measure, adaptive_defaults={a.dest: a.default for a in options})

    p = subparsers.add_parser("instrument", help="instrument tools (the simulator)")
    tools = p.add_subparsers(dest="tool", required=True, metavar="TOOL")
    p = tools.add_parser(
        "simulate", help="a simulated goniometer on a pseudo-terminal",
        description="Serve the instrument protocol on a new pseudo-terminal, with detector "
                    "voltages from a BRDF and a PTFE reference plate. Prints the device path "
                    "as its first line of output, then serves until killed.")
    sample = p.add_mutually_exclusive_group(required=True)
    sample.add_argument("--params",
                        help="the parameters of a model sample (kb,kr,a,b,kd for five, or a "
                             "paper sample name; see --model)")
    sample.add_argument("--data", metavar="FILE",
                        help="interpolate this in-plane measurement file instead")
    add_model_option(p, "the model of --params")
    add_reader_options(p)
    p.add_argument("--reference-reflectance", type=float, default=0.99, metavar="RHO",
                   help="the simulated PTFE plate's reflectance (default 0.99)")
    p.add_argument("--gain", type=float, default=3.0,
                   help="volts per unit of projected BRDF (default 3)")
    p.add_argument("--noise", type=float, default=0.01,
                   help="relative noise of a 10 ms integration (default 0.01)")
    p.add_argument("--seed", type=int, default=0, help="seeds the noise and the faults")
    p.add_argument("--baud", type=int, default=115200, help="line speed (default 115200)")
    p.add_argument("--motor-speed", type=float, default=20.0, metavar="DEG_PER_S",
                   help="motor speed (default 20)")
    p.add_argument("--changer-seconds", type=float, default=1.0,
                   help="time to swap sample and reference (default 1)")
    p.add_argument("--wavelength-nm", type=float, default=1060.0,
                   help="reported by IDN? (default 1060, the paper's)")
    faults = p.add_argument_group("fault injection (for tests)")
    faults.add_argument("--drop-rate", type=float, default=0.0,
                        help="chance that a line loses one byte")
    faults.add_argument("--corrupt-rate", type=float, default=0.0,
                        help="chance that a line has one byte replaced")
    faults.add_argument("--stall-rate", type=float, default=0.0,
                        help="chance that a reply line is delayed by --stall-seconds")
    faults.add_argument("--stall-seconds", type=float, default=1.0,
                        help="how long a stalled reply line waits (default 1)")
    faults.add_argument("--disconnect-after", type=int, metavar="N",
                        help="answer N commands, then hang up")
    p.set_defaults(run=run_simulate)


def scan_plan(args):
    """The `~brdfjax.instrument.plan.Plan` of ``--plan`` or of the in-plane scan options."""
    from brdfjax.instrument.plan import Plan, load_plan

    given = [f"--{name.replace('_', '-')}" for name in PLAN_OPTIONS
             if getattr(args, name) is not None]
    if args.plan:
        if given:
            raise ValueError(f"not with --plan: put {', '.join(given)} in the plan file")
        return load_plan(args.plan)
    maximum = 85.0 if args.theta_r_max is None else args.theta_r_max
    options = {"theta_r": (-maximum, maximum, args.theta_r_step or 1.0),
               "azimuth": args.azimuth, "average": args.average,
               "integration_ms": args.integration_ms, "beam_margin": args.beam_margin}
    return Plan(incidence=args.incidence,
                **{k: v for k, v in options.items() if v is not None})


def require_driver() -> None:
    """pyserial, or the one-line error naming the extra that installs it; asked after the
    settings are checked, so that a bad setting is named whatever is installed."""
    from brdfjax.optional import require

    require("serial", "instrument", "the instrument driver (brdfjax measure)", "pyserial")


def run_measure(args) -> None:
    from pathlib import Path

    from brdfjax.instrument.acquire import measure

    plan = scan_plan(args)
    journal = args.journal or Path(args.out).with_suffix(".journal.jsonl")  # measure's default
    check_writable({"--out": args.out, "--journal": journal})
    if args.adaptive:
        run_adaptive(args, plan)
        return
    given = [f"--{name.replace('_', '-')}" for name, default in args.adaptive_defaults.items()
             if getattr(args, name) != default]
    if given:
        raise ValueError(f"{', '.join(given)}: only with --adaptive")
    require_driver()
    print(f"plan: {len(plan.points)} geometries x (sample + reference); {plan.blocked} "
          "skipped where the detector would block the source", file=sys.stderr)
    result = measure(args.port, plan, args.out, journal=args.journal,
                     reference_reflectance=args.reference_reflectance, baud=args.baud,
                     timeout=args.timeout, retries=args.retries,
                     metadata={"sample": args.sample or Path(args.out).stem}, progress=not args.quiet)
    print(f"wrote {len(result.data)} points to {args.out} ({result.read_now} readings now, "
          f"{result.resumed} from the journal {result.journal}; {result.resends} commands "
          "resent)")


def run_adaptive(args, region) -> None:
    """``measure --adaptive``: `brdfjax.instrument.adaptive.measure_adaptive` over the
    plan's geometries, its report printed and its figure written."""
    from pathlib import Path

    from brdfjax.cache import enable
    from brdfjax.data.formats import load_geometry
    from brdfjax.instrument.adaptive import check_settings, measure_adaptive, region_geometry

    figure = args.plot or str(Path(args.out).with_suffix(".adaptive.png"))
    check_writable(figures={"--plot": figure})
    candidates = None
    if args.candidates is not None:
        from brdfjax.data.measurements import DataError

        try:
            candidates = load_geometry(args.candidates)
        except DataError as problem:
            raise ValueError(f"--candidates: {problem}") from None
    settings = {"target_width": args.target_width / 100, "model": args.model,
                "start": args.start, "batch": args.batch, "max_readings": args.max_readings,
                "max_minutes": args.max_minutes}
    check_settings(region_geometry(region), candidates, **settings)
    require_driver()
    enable()
    print(f"adaptive: predicting over the plan's {len(region.points)} geometries; stop at a "
          f"median 95 % half-width of {args.target_width:g} %", file=sys.stderr)
    result = measure_adaptive(
        args.port, region, args.out, candidates=candidates, seed=args.seed, **settings,
        journal=args.journal,
        reference_reflectance=args.reference_reflectance, baud=args.baud,
        timeout=args.timeout, retries=args.retries,
        metadata={"sample": args.sample or Path(args.out).stem}, progress=not args.quiet,
        plot=figure)
    for line in result.report():
        print(line)
    print(f"wrote {len(result.data)} points to {args.out} and the figure {figure} "
          f"({result.read_now} readings now, {result.resumed} from the journal "
          f"{result.journal}; {result.resends} commands resent)")


def run_simulate(args) -> None:
    from brdfjax.instrument.simulator import DataSample, Device, Faults, ModelSample, Server

    if args.params is not None:
        from brdfjax.cache import enable

        enable()
        sample = ModelSample(parameters(args.params, args.model), args.model)
    else:
        from brdfjax.data.formats import load

        sample = DataSample(load(args.data, **reader_options(args)))
    device = Device(sample, reference_reflectance=args.reference_reflectance, gain=args.gain,
                    noise=args.noise, seed=args.seed, motor_speed=args.motor_speed,
                    changer_seconds=args.changer_seconds, baud=args.baud,
                    wavelength_nm=args.wavelength_nm)
    faults = Faults(drop_rate=args.drop_rate, corrupt_rate=args.corrupt_rate,
                    stall_rate=args.stall_rate, stall_seconds=args.stall_seconds,
                    disconnect_after=args.disconnect_after)
    server = Server(device, faults, seed=args.seed)
    print(server.path, flush=True)
    print(f"simulator: serving on {server.path} at {args.baud} baud; stop with Ctrl-C",
          file=sys.stderr, flush=True)
    server.serve_forever()
