"""Line-by-line numpy transcriptions of the paper's Eq. (1)-(5) and of the other models'
formulas as their modules' docstrings (the docs' Models page) state them.

Independent of brdfjax's rearranged formulas: valid at generic points only (they divide by
zero at the specular point and at grazing angles, exactly where the printed forms break).
Every function takes numpy arrays (``np.longdouble`` for a reference to the last digits).
"""

import functools
import math

import numpy as np

PAPER_CONSTANTS = (0.0136, 0.0141, 9.0, 1.0)  # sigma_sph, sigma_r, u_sph, v_sph


def generic_points(count, seed, in_plane):
    """Random angles away from the points where the printed formulas divide by zero."""
    rng = np.random.default_rng(seed)
    ti, tr = rng.uniform(0.02, 1.45, (2, 4 * count))
    pr = (np.where(rng.random(4 * count) < 0.5, 0.0, np.pi) if in_plane
          else rng.uniform(0, 2 * np.pi, 4 * count))
    far = (np.abs(ti - tr) > 0.02) | (np.abs(np.sin(pr / 2)) < 0.9)
    return ti[far][:count], tr[far][:count], pr[far][:count]


def directions(ti, tr, pr):
    """w_i = (sin ti, 0, cos ti) and w_r = (sin tr cos pr, sin tr sin pr, cos tr)."""
    zero = np.zeros_like(ti * tr * pr)
    w_i = np.stack([np.sin(ti) + zero, zero, np.cos(ti) + zero])
    w_r = np.stack([np.sin(tr) * np.cos(pr), np.sin(tr) * np.sin(pr), np.cos(tr) + zero])
    return w_i, w_r


def half_vector(ti, tr, pr):
    """cos th = h_z and cos td = w_i . h with h = (w_i + w_r) / |w_i + w_r|."""
    w_i, w_r = directions(ti, tr, pr)
    s = w_i + w_r
    h = s / np.sqrt(np.sum(s * s, axis=0))
    return h[2], np.sum(w_i * h, axis=0)


def shadowing(ti, tr, pr, constants=PAPER_CONSTANTS):
    """G of Eq. (3)-(4) as printed, and the facet tilt alpha and cos gamma of Eq. (1)."""
    sigma_sph, sigma_r, u_sph, v_sph = constants
    cos_g = np.sqrt(0.5 * (np.cos(ti) * np.cos(tr) + np.sin(ti) * np.sin(tr) * np.cos(pr) + 1))
    cos_alpha = (np.cos(ti) + np.cos(tr)) / (2 * cos_g)
    alpha = np.arccos(np.clip(cos_alpha, -1, 1))
    w = sigma_sph * (1 + u_sph * np.sin(alpha) / (np.sin(alpha) + v_sph * np.cos(alpha)))
    denom = 2 * np.sin(alpha) * cos_g
    tan_i = np.tan(ti) * (np.sin(ti) + np.sin(tr) * np.cos(pr)) / denom
    tan_r = np.tan(tr) * (np.sin(tr) + np.sin(ti) * np.cos(pr)) / denom
    tan_g = np.abs(np.cos(ti) - cos_g) / denom
    G = (1 + w * np.abs(tan_i * tan_r) / (1 + sigma_r * tan_g)) / (
        (1 + w * tan_i**2) * (1 + w * tan_r**2))
    return G, alpha, cos_g


def brdf(kb, kr, a, b, kd, ti, tr, pr, constants=PAPER_CONSTANTS):
    """The five-parameter model, Eq. (5)."""
    G, alpha, cos_g = shadowing(ti, tr, pr, constants)
    D = kr**2 * np.cos(alpha) / (1 + (kr**2 - 1) * np.cos(alpha) ** 2)
    R0 = np.exp(b * (1 - cos_g) ** a)
    return kb * D * R0 * G / np.cos(tr) + kd


def torrance_sparrow(g, c, n, rho0, ti, tr, pr):
    """The paper's Eq. (2) written out."""
    G, _, _ = shadowing(ti, tr, pr)
    cos_th, cos_td = half_vector(ti, tr, pr)
    th = np.arccos(cos_th)
    sin_tt = np.sin(np.arccos(cos_td)) / n
    cos_tt = np.cos(np.arcsin(sin_tt))
    R = ((cos_td - n * cos_tt) ** 2 / (cos_td + n * cos_tt) ** 2
         + (n * cos_td - cos_tt) ** 2 / (n * cos_td + cos_tt) ** 2) / 2
    return g * R * G / np.cos(tr) * np.exp(-(c**2) * th**2) + rho0 / np.pi * np.cos(ti)


def schlick(f0, cos_td):
    return f0 + (1 - f0) * (1 - cos_td) ** 5


def ggx(ks, alpha, f0, kd, ti, tr, pr):
    cos_th, cos_td = half_vector(ti, tr, pr)
    D = alpha**2 / (np.pi * (cos_th**2 * (alpha**2 - 1) + 1) ** 2)

    def G1(t):
        return 2 / (1 + np.sqrt(1 + alpha**2 * np.tan(t) ** 2))

    return kd + ks * D * G1(ti) * G1(tr) * schlick(f0, cos_td) / (4 * np.cos(ti) * np.cos(tr))


_erf = np.vectorize(math.erf, otypes=[float])


def beckmann(ks, alpha, f0, kd, ti, tr, pr):
    cos_th, cos_td = half_vector(ti, tr, pr)
    tan2_th = (1 - cos_th**2) / cos_th**2
    D = np.exp(-tan2_th / alpha**2) / (np.pi * alpha**2 * cos_th**4)

    def G1(t):
        m = 1 / (alpha * np.tan(t))
        lam = (_erf(np.asarray(m, dtype=float)) - 1) / 2 + np.exp(-(m**2)) / (2 * m * np.sqrt(np.pi))
        return 1 / (1 + lam)

    return kd + ks * D * G1(ti) * G1(tr) * schlick(f0, cos_td) / (4 * np.cos(ti) * np.cos(tr))


def lambert(kd, ti, tr, pr):
    return kd + 0 * (ti + tr + pr)


def rpv(rho0, k, asymmetry, rhoc, ti, tr, pr):
    M = np.cos(ti) ** (k - 1) * np.cos(tr) ** (k - 1) / (np.cos(ti) + np.cos(tr)) ** (1 - k)
    w_i, w_r = directions(ti, tr, pr)
    cos_g = np.sum(w_i * w_r, axis=0)
    F = (1 - asymmetry**2) / (1 + 2 * asymmetry * cos_g + asymmetry**2) ** 1.5
    Gd = np.sqrt(np.tan(ti) ** 2 + np.tan(tr) ** 2 - 2 * np.tan(ti) * np.tan(tr) * np.cos(pr))
    H = 1 + (1 - rhoc) / (1 + Gd)
    return rho0 / np.pi * M * F * H


def cos_phase(ti, tr, pr):
    """cos g = w_i . w_r, as the Ross-Li and back-scatter docstrings write it."""
    return np.cos(ti) * np.cos(tr) + np.sin(ti) * np.sin(tr) * np.cos(pr)


def backscatter(kb, beta, ti, tr, pr):
    c = np.maximum(cos_phase(ti, tr, pr), 0)
    return kb * beta**2 / (np.pi * (c**2 * (beta**2 - 1) + 1) ** 2)


def abg(A, B, g, ti, tr, pr):
    distance = np.hypot(np.sin(tr) * np.cos(pr) + np.sin(ti), np.sin(tr) * np.sin(pr))
    return A / (B + distance**g)


def ross_li(f_iso, f_vol, f_geo, ti, tr, pr, h_b=2.0):
    """MODIS MCD43 RossThick-LiSparseReciprocal, with arccos and tangents as printed."""
    cos_xi = cos_phase(ti, tr, pr)
    xi = np.arccos(np.clip(cos_xi, -1, 1))
    k_vol = ((np.pi / 2 - xi) * np.cos(xi) + np.sin(xi)) / (np.cos(ti) + np.cos(tr)) - np.pi / 4
    sec_i, sec_r = 1 / np.cos(ti), 1 / np.cos(tr)
    D = np.sqrt(np.tan(ti) ** 2 + np.tan(tr) ** 2 - 2 * np.tan(ti) * np.tan(tr) * np.cos(pr))
    cos_t = np.clip(h_b * np.sqrt(D**2 + (np.tan(ti) * np.tan(tr) * np.sin(pr)) ** 2)
                    / (sec_i + sec_r), -1, 1)
    t = np.arccos(cos_t)
    O = (t - np.sin(t) * np.cos(t)) * (sec_i + sec_r) / np.pi
    k_geo = O - sec_i - sec_r + (1 + cos_xi) * sec_i * sec_r / 2
    return (f_iso + f_vol * k_vol + f_geo * k_geo) / np.pi


# Sums by brdfjax's naming rule (`brdfjax.models.sum`), the shared kd once, in the first part.
def ggx_backscatter(ks, alpha, f0, kd, kb, beta, ti, tr, pr):
    return ggx(ks, alpha, f0, kd, ti, tr, pr) + backscatter(kb, beta, ti, tr, pr)


def ggx_ggx(ks, alpha, f0, kd, ks_2, alpha_2, f0_2, ti, tr, pr):
    return ggx(ks, alpha, f0, kd, ti, tr, pr) + ggx(ks_2, alpha_2, f0_2, 0, ti, tr, pr)


def abg_lambert(A, B, g, kd, ti, tr, pr):
    return abg(A, B, g, ti, tr, pr) + lambert(kd, ti, tr, pr)


MODELS = {"five": brdf, "torrance-sparrow": torrance_sparrow, "ggx": ggx,
          "beckmann": beckmann, "lambert": lambert, "rpv": rpv, "backscatter": backscatter,
          "abg": abg, "ross-li": ross_li, "ggx+backscatter": ggx_backscatter,
          "ggx+ggx": ggx_ggx, "abg+lambert": abg_lambert}


# ---- Eq. (9) by an integrator that shares nothing with brdfjax.models.hemispherical

@functools.cache
def reflectance(name, params, ti, peak="back-scatter", tol=1e-7):
    """rho(ti) = integral of f_r cos(tr) d(omega), by nested adaptive quadrature (scipy quad).

    Plain (theta_r, phi_r) coordinates, with breaks where the integrand is sharp: at
    ``tr = ti`` in theta_r, and 0.05 rad from the peak's azimuth (0 for back-scatter, pi for
    specular) in phi_r; the integrand is even in phi_r, so [0, pi] is integrated and
    doubled. Points where the printed formula is 0/0 (a set of measure zero) count as 0.
    Cached: the same integral is asked for by several tests.
    """
    from scipy.integrate import quad

    formula = MODELS[name]

    def inner(pr):
        def integrand(tr):
            with np.errstate(all="ignore"):
                value = float(formula(*params, ti, tr, pr))
            return value * math.cos(tr) * math.sin(tr) if math.isfinite(value) else 0.0

        points = [ti] if 0 < ti < math.pi / 2 else None
        return quad(integrand, 0, math.pi / 2, points=points, epsabs=tol / 10, epsrel=tol,
                    limit=200)[0]

    width = 0.05
    split = width if peak == "back-scatter" else math.pi - width
    return 2 * sum(quad(inner, low, high, epsabs=tol / 10, epsrel=tol, limit=200)[0]
                   for low, high in ((0.0, split), (split, math.pi)))
