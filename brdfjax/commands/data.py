"""Commands on data and the bare model: ``eval``, ``reflectance``, ``convert``, ``info``."""

from __future__ import annotations

import numpy as np

from brdfjax.commands import (
    add_model_option,
    add_reader_options,
    angles,
    check_writable,
    parameters,
    reader_options,
    zeniths,
)


def register(subparsers) -> None:
    p = subparsers.add_parser("eval", help="model BRDF at given angles",
                              description="Print f_r (and f_r cos theta_r) as CSV for every "
                                          "combination of the given angles (degrees).")
    p.add_argument("--params", required=True,
                   help="the model's parameters in order (kb,kr,a,b,kd for five) or a paper "
                        "sample name")
    add_model_option(p)
    p.add_argument("--theta-i", type=zeniths, required=True, help="incidence angles (deg)")
    p.add_argument("--theta-r", type=zeniths, required=True, help="reflection zenith (deg)")
    p.add_argument("--phi-r", type=angles, default=np.array([180.0]),
                   help="reflection azimuth (deg; 180 = specular side; default 180)")
    p.set_defaults(run=run_eval)

    p = subparsers.add_parser("reflectance", help="directional-hemispherical reflectance",
                              description="Eq. (9): rho(theta_i), the fraction of light "
                                          "reflected into the whole hemisphere.")
    p.add_argument("--params", required=True,
                   help="the model's parameters in order (kb,kr,a,b,kd for five) or a paper "
                        "sample name")
    add_model_option(p)
    p.add_argument("--theta-i", type=zeniths, default=np.array([0.0, 30.0, 60.0]),
                   help="incidence angles (deg; default 0,30,60)")
    p.set_defaults(run=run_reflectance)

    p = subparsers.add_parser("convert", help="convert between measurement formats",
                              description="Read any supported file and write brdfjax CSV "
                                          "(.csv), Zemax tabular BSDF (.bsdf) or ASTM "
                                          "E1392 (.astm).")
    p.add_argument("input", help="the file to read (any format `brdfjax fit` reads)")
    p.add_argument("output", help="the file to write: .csv (brdfjax CSV), .bsdf (Zemax) "
                                  "or .astm (ASTM E1392)")
    add_reader_options(p)
    p.set_defaults(run=run_convert)

    p = subparsers.add_parser("info", help="summary of a measurement file",
                              description="What brdfjax reads from a measurement file: its "
                                          "metadata, points, incidences and the ranges of "
                                          "theta_r and BRDF.")
    p.add_argument("file", help="the measurement file (any format `brdfjax fit` reads)")
    add_reader_options(p)
    p.set_defaults(run=run_info)


def run_eval(args) -> None:
    from brdfjax.models.paper import brdf

    ti, tr, pr = np.meshgrid(args.theta_i, args.theta_r, args.phi_r, indexing="ij")
    params = parameters(args.params, args.model)
    values = np.asarray(brdf(params, *np.radians([ti, tr, pr]), model=args.model))
    print("theta_i,theta_r,phi_r,brdf,projected")
    for row in zip(ti.ravel(), tr.ravel(), pr.ravel(), values.ravel()):
        print(f"{row[0]:g},{row[1]:g},{row[2]:g},{row[3]:.10g},"
              f"{row[3] * np.cos(np.radians(row[1])):.10g}")


def run_reflectance(args) -> None:
    from brdfjax.models.hemispherical import energy_warning, reflectance

    rho = np.asarray(reflectance(parameters(args.params, args.model), np.radians(args.theta_i),
                                 model=args.model, warn=False))
    print("theta_i,reflectance")
    for t, r in zip(args.theta_i, rho):
        print(f"{t:g},{r:.6f}")
    warning = energy_warning(rho)
    if warning:
        print(f"warning: {warning}")


def run_convert(args) -> None:
    from brdfjax.data.formats import load, save

    check_writable({"output": args.output})
    data = load(args.input, **reader_options(args))
    save(data, args.output)
    print(f"wrote {len(data)} points to {args.output}")


# Up to this many distinct incidences are listed one by one; more are summarised as bins.
LISTED_INCIDENCES = 12


def run_info(args) -> None:
    from brdfjax.data.formats import load, load_spectral

    options = reader_options(args)
    if "wavelength_nm" not in options and _spectral(args.file):
        spectra = load_spectral(args.file)
        if len(spectra) > 1:
            return info_of_wavelengths(args.file, spectra)
    data = load(args.file, **options)
    print(f"file:        {args.file}")
    for key, value in data.metadata.items():
        print(f"{key + ':':<12} {value}")
    print(f"points:      {len(data)}")
    print(f"in-plane:    {'yes' if data.in_plane else 'no'}")
    print(f"incidences:  {describe_incidences(data)}")
    tr = np.degrees(data.theta_r)
    print(f"theta_r:     {tr.min():g} to {tr.max():g} deg")
    print(f"brdf:        {data.brdf.min():.4g} to {data.brdf.max():.4g} 1/sr")
    print(f"sigma:       {'given' if data.sigma is not None else 'none'}")
    print(f"repeats:     {describe_repeats(data)}")


def _spectral(path) -> bool:
    """Whether the file's format may hold several wavelengths (NIST, ASTM)."""
    from brdfjax.data.formats import _reader

    return hasattr(_reader(path), "read_spectral")


def info_of_wavelengths(path, spectra: dict) -> None:
    """`info` of a file of several wavelengths: one line per wavelength, then how to pick
    one (``--wavelength``) for the full summary."""
    first = next(iter(spectra.values()))
    print(f"file:        {path}")
    print(f"wavelengths: {len(spectra)}: {', '.join(f'{w:g}' for w in spectra)} nm")
    for key, value in first.metadata.items():
        if key != "wavelength_nm":
            print(f"{key + ':':<12} {value}")
    print(f"{'nm':>8} {'points':>7}  {'incidences':<40} brdf (1/sr)")
    for wavelength, data in spectra.items():
        print(f"{wavelength:>8g} {len(data):>7}  {describe_incidences(data):<40} "
              f"{data.brdf.min():.4g} to {data.brdf.max():.4g}")
    print("each wavelength in full: brdfjax info FILE --wavelength NM; fit all at once: "
          "brdfjax batch FILE --wavelength all --out results.csv")


def describe_incidences(data) -> str:
    """The distinct incidences, or their range and bins when there are many."""
    distinct = data.incidences_deg
    if len(distinct) <= LISTED_INCIDENCES:
        return f"{', '.join(f'{x:g}' for x in distinct)} deg"
    bins = data.incidence_bins()
    counts = np.bincount(bins.index)
    listing = ", ".join(f"{label.removesuffix(' deg')} ({n})"
                        for label, n in zip(bins.labels, counts))
    return (f"{len(distinct)} distinct, {distinct.min():g} to {distinct.max():g} deg; "
            f"bins (points): {listing} deg")


def describe_repeats(data) -> str:
    """How many geometries were read more than once, and how much their readings differ."""
    from brdfjax.data.measurements import repeat_summary

    summary = repeat_summary(data)
    if summary.geometries == 0:
        return "none (every geometry read once)"
    text = (f"{summary.geometries} geometries read more than once ({summary.readings} "
            f"readings, up to {summary.most} at one geometry)")
    if np.isfinite(summary.median_spread):
        text += (f"; spread of their readings (std / mean): median "
                 f"{100 * summary.median_spread:.3g} %, max {100 * summary.max_spread:.3g} %")
    return text
