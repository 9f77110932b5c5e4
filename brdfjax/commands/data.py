"""Commands on data and the bare model: ``eval``, ``reflectance``, ``convert``, ``info``."""

from __future__ import annotations

import numpy as np

from brdfjax.commands import (
    add_reader_options,
    angles,
    check_writable,
    parameters,
    reader_options,
)


def register(subparsers) -> None:
    p = subparsers.add_parser("eval", help="model BRDF at given angles",
                              description="Print f_r (and f_r cos theta_r) as CSV for every "
                                          "combination of the given angles (degrees).")
    p.add_argument("--params", type=parameters, required=True,
                   help="kb,kr,a,b,kd or a paper sample name")
    p.add_argument("--theta-i", type=angles, required=True, help="incidence angles (deg)")
    p.add_argument("--theta-r", type=angles, required=True, help="reflection zenith (deg)")
    p.add_argument("--phi-r", type=angles, default=np.array([180.0]),
                   help="reflection azimuth (deg; 180 = specular side; default 180)")
    p.set_defaults(run=run_eval)

    p = subparsers.add_parser("reflectance", help="directional-hemispherical reflectance",
                              description="Eq. (9): rho(theta_i), the fraction of light "
                                          "reflected into the whole hemisphere.")
    p.add_argument("--params", type=parameters, required=True,
                   help="kb,kr,a,b,kd or a paper sample name")
    p.add_argument("--theta-i", type=angles, default=np.array([0.0, 30.0, 60.0]),
                   help="incidence angles (deg; default 0,30,60)")
    p.set_defaults(run=run_reflectance)

    p = subparsers.add_parser("convert", help="convert between measurement formats",
                              description="Read any supported file and write brdfjax CSV "
                                          "(.csv) or Zemax tabular BSDF (.bsdf).")
    p.add_argument("input", help="the file to read (any format `brdfjax fit` reads)")
    p.add_argument("output", help="the file to write: .csv (brdfjax CSV) or .bsdf (Zemax)")
    add_reader_options(p)
    p.set_defaults(run=run_convert)

    p = subparsers.add_parser("info", help="summary of a measurement file")
    p.add_argument("file", help="the measurement file (any format `brdfjax fit` reads)")
    add_reader_options(p)
    p.set_defaults(run=run_info)


def run_eval(args) -> None:
    from brdfjax.model import brdf

    ti, tr, pr = np.meshgrid(args.theta_i, args.theta_r, args.phi_r, indexing="ij")
    values = np.asarray(brdf(args.params, *np.radians([ti, tr, pr])))
    print("theta_i,theta_r,phi_r,brdf,projected")
    for row in zip(ti.ravel(), tr.ravel(), pr.ravel(), values.ravel()):
        print(f"{row[0]:g},{row[1]:g},{row[2]:g},{row[3]:.10g},"
              f"{row[3] * np.cos(np.radians(row[1])):.10g}")


def run_reflectance(args) -> None:
    from brdfjax.hemispherical import energy_warning, reflectance

    rho = np.asarray(reflectance(args.params, np.radians(args.theta_i)))
    print("theta_i,reflectance")
    for t, r in zip(args.theta_i, rho):
        print(f"{t:g},{r:.6f}")
    warning = energy_warning(rho)
    if warning:
        print(f"warning: {warning}")


def run_convert(args) -> None:
    from brdfjax.formats import load, save

    check_writable({"output": args.output})
    data = load(args.input, **reader_options(args))
    save(data, args.output)
    print(f"wrote {len(data)} points to {args.output}")


def run_info(args) -> None:
    from brdfjax.formats import load

    data = load(args.file, **reader_options(args))
    print(f"file:        {args.file}")
    for key, value in data.metadata.items():
        print(f"{key + ':':<12} {value}")
    print(f"points:      {len(data)}")
    print(f"in-plane:    {'yes' if data.in_plane else 'no'}")
    print(f"incidences:  {', '.join(f'{x:g}' for x in data.incidences_deg)} deg")
    tr = np.degrees(data.theta_r)
    print(f"theta_r:     {tr.min():g} to {tr.max():g} deg")
    print(f"brdf:        {data.brdf.min():.4g} to {data.brdf.max():.4g} 1/sr")
    print(f"sigma:       {'given' if data.sigma is not None else 'none'}")
